"""Runs: a config (a dict, or a TOML file) run into a folder through the run API the
``ifslab`` command line and the sweeps call, and its results read back as NumPy arrays and
dicts."""

from __future__ import annotations

import csv
import json
import math
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Dict, Iterable, List, Mapping, Optional, Union

import numpy as np

from . import _ifslab
from ._code import code_arg
from ._images import load_image, save_image
from ._progress import reporting

PathLike = Union[str, "os.PathLike[str]"]


@dataclass
class Result:
    """A finished run: its folder and what it wrote there, read back."""

    #: The run folder (``config.toml``, ``summary.json``, ``log.csv``, pictures, …).
    dir: Path
    #: The problem (``"image"``, ``"points"``, ``"sdf"``, ``"flame"``, ``"texture"``, ``"image3d"``).
    problem: str
    #: The line the command line prints at the end.
    headline: str
    #: ``summary.json``.
    summary: Dict[str, Any]
    #: The recovered code (``code.json``) as a dict, where the run writes one.
    code: Optional[Dict[str, Any]] = None
    #: The run's log (``log.csv``, or a points fit's ``history.csv``), column by column.
    log: Dict[str, np.ndarray] = field(default_factory=dict)

    @property
    def config(self) -> Dict[str, Any]:
        """The resolved config the run wrote (``config.toml``), every default spelt out."""
        return json.loads(_ifslab.resolve_config("resume", os.fspath(self.dir)))

    def image(self, name: str = "render.png", rgb: bool = False) -> np.ndarray:
        """A picture of the run folder (``render.png``, ``target.png``, ``zoom_strip.png``,
        ``loss.png``, …) as a float32 array in [0, 1]."""
        return load_image(self.dir / name, rgb=rgb)

    def file(self, name: str) -> Path:
        """A file of the run folder."""
        return self.dir / name

    def __repr__(self) -> str:
        return f"Result({self.problem!r}, dir={str(self.dir)!r}, headline={self.headline!r})"


def _read_csv(path: Path) -> Dict[str, np.ndarray]:
    if not path.is_file():
        return {}
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return {}
    header, body = rows[0], rows[1:]

    def number(text: str) -> float:
        try:
            return float(text)
        except ValueError:
            return math.nan

    return {
        name: np.array([number(r[i]) if i < len(r) else math.nan for r in body])
        for i, name in enumerate(header)
    }


def _result(dir: Path, report: Dict[str, Any]) -> Result:
    code_file = dir / "code.json"
    code = json.loads(_ifslab.load_code(os.fspath(code_file))) if code_file.is_file() else None
    log = _read_csv(dir / "log.csv") or _read_csv(dir / "history.csv")
    return Result(
        dir=dir,
        problem=report["problem"],
        headline=report["headline"],
        summary=report["summary"],
        code=code,
        log=log,
    )


def load_run(dir: PathLike) -> Result:
    """A finished run folder (one this package or the command line made) read back."""
    dir = Path(dir)
    config = json.loads(_ifslab.resolve_config("resume", os.fspath(dir)))
    with open(dir / "summary.json") as f:
        summary = json.load(f)
    return _result(dir, {"problem": config.get("problem", "image"), "headline": "", "summary": summary})


def _output_dir(output: Optional[PathLike], problem: str) -> Path:
    if output is None:
        return Path(tempfile.mkdtemp(prefix=f"ifslab-{problem}-"))
    return Path(output)


def _merge(base: Dict[str, Any], extra: Mapping[str, Any]) -> Dict[str, Any]:
    """``extra`` written into ``base``: nested dicts merged key by key, a dotted key or
    one spelt with ``__`` (``renderer__sigma``) going into its table, ``None`` left out."""
    for key, value in extra.items():
        if value is None:
            continue
        parts = key.replace("__", ".").split(".")
        table = base
        for p in parts[:-1]:
            table = table.setdefault(p, {})
        last = parts[-1]
        if isinstance(value, Mapping) and isinstance(table.get(last), dict):
            _merge(table[last], value)
        elif isinstance(value, Mapping):
            table[last] = _merge({}, value)
        else:
            table[last] = value
    return base


def _plain(value: Any) -> Any:
    """NumPy numbers and paths as JSON takes them."""
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, os.PathLike):
        return os.fspath(value)
    return value


def _overrides(set: Optional[Mapping[str, Any]]) -> List[str]:
    """``{"renderer.sigma": 0.8}`` as ``ifslab run --set`` takes it."""
    return [f"{k}={json.dumps(_plain(v))}" for k, v in (set or {}).items()]


def _run(
    source: str,
    config: str,
    dir: Path,
    resume: bool,
    progress: Any,
    overrides: Iterable[str] = (),
) -> Result:
    with reporting(progress) as callback:
        report = _ifslab.run(source, config, os.fspath(dir), resume, list(overrides), callback)
    return _result(dir, json.loads(report))


def resolve_config(config: Union[Mapping[str, Any], PathLike], set: Optional[Mapping[str, Any]] = None) -> Dict[str, Any]:
    """The resolved config of ``config`` (a dict or a TOML file): what ``config.toml`` of
    its run folder will hold, every default written out."""
    if isinstance(config, Mapping):
        return json.loads(_ifslab.resolve_config("dict", json.dumps(_plain(dict(config))), _overrides(set)))
    return json.loads(_ifslab.resolve_config("file", os.fspath(config), _overrides(set)))


def run(
    config: Union[Mapping[str, Any], PathLike, None] = None,
    output: Optional[PathLike] = None,
    *,
    resume: Optional[PathLike] = None,
    set: Optional[Mapping[str, Any]] = None,
    progress: Any = None,
) -> Result:
    """Runs any config ``ifslab run`` accepts — a dict (TOML's tables as dicts; its
    ``problem`` key picks the problem) or a TOML file, with ``set`` overriding keys as
    ``--set`` does — into ``output`` (a fresh folder; a temporary one when ``None``).
    ``resume=DIR`` continues an interrupted run from its checkpoint, bit-identically."""
    if resume is not None:
        dir = Path(resume)
        return _run("resume", os.fspath(dir), dir, True, progress)
    if config is None:
        raise TypeError("run() needs a config (a dict or a TOML file) or resume=DIR")
    if isinstance(config, Mapping):
        problem = str(config.get("problem", "image"))
        dir = _output_dir(output, problem)
        return _run("dict", json.dumps(_plain(dict(config))), dir, False, progress, _overrides(set))
    dir = _output_dir(output, "run")
    return _run("file", os.fspath(config), dir, False, progress, _overrides(set))


class _Inputs:
    """Arrays handed to a run as the files its config names, written to a temporary folder
    beside (not inside) the run folder and kept, so that ``resume`` finds them again."""

    def __init__(self) -> None:
        self._dir: Optional[Path] = None

    def path(self, name: str) -> Path:
        if self._dir is None:
            self._dir = Path(tempfile.mkdtemp(prefix="ifslab-inputs-"))
        return self._dir / name

    def picture(self, image: Any, name: str = "target.png") -> str:
        """A picture argument as a file name: arrays written as PNG, paths as they are."""
        if isinstance(image, (str, os.PathLike)):
            return os.path.abspath(os.fspath(image))
        path = self.path(name)
        save_image(np.asarray(image), path)
        return os.fspath(path)

    def __enter__(self) -> "_Inputs":
        return self

    def __exit__(self, *exc: Any) -> None:
        pass


def invert(
    image: Any = None,
    maps: int = 3,
    output: Optional[PathLike] = None,
    *,
    resume: Optional[PathLike] = None,
    progress: Any = None,
    **config: Any,
) -> Result:
    """Recovers an IFS code from a picture, as ``ifslab invert`` does: ``image`` is an
    array (grey ``(H, W)`` or colour, floats in [0, 1] or integers), a picture file, or a
    code (dict, ``.json`` file or built-in name) whose render is the target.

    The command line's flags are keywords of the same names (``size``, ``init``,
    ``sigma_final``, ``trajectories``, ``lpips``, ``strategy="adam"``, …) at its defaults
    (``size=128``, ``supersample=4``, ``sigma=1.0``, ``seed=0``, ``checkpoint_every=100``,
    svd maps); everything else is an image config's key (``iterations=200``, ``paper=True``,
    ``strategy={"kind": "adam"}``, ``renderer__sigma_final=0.5`` or
    ``**{"renderer.sigma_final": 0.5}``), resolved by the recipe exactly as
    ``ifslab run`` resolves it. The run goes into ``output`` (a temporary folder when
    ``None``); ``resume=DIR`` continues an interrupted one.
    """
    if resume is not None:
        return run(resume=resume, progress=progress)
    if image is None:
        raise TypeError("invert() needs an image (array, picture file or code) or resume=DIR")
    # `ifslab invert`'s flags and the config keys they set (experiments/src/cmd/invert.rs).
    flags = {
        "size": "target.size",
        "polarity": "target.polarity",
        "family": "model.family",
        "param": "model.parameterisation",
        "init": "model.init",
        "start_size": "model.start_size",
        "collage_refine": "model.collage_refine",
        "cells": "target.cells",
        "trajectories": "generator.trajectories",
        "length": "generator.length",
        "supersample": "renderer.supersample",
        "sigma": "renderer.sigma",
        "sigma_final": "renderer.sigma_final",
        "device": "renderer.device",
        "lpips": "loss.lpips_weight",
    }
    strategy = config.get("strategy")
    if isinstance(strategy, str):
        # As `--strategy NAME`: hyphens or underscores, and `hybrid` from a fitted start
        # (collage or EM) is the cold hybrid, whose annealing keeps the fit.
        name = strategy.replace("-", "_")
        start = config.get("init", "random" if config.get("paper") else "collage")
        if name == "hybrid" and start != "random":
            name = "cold_hybrid"
        config = dict(config, strategy={"kind": name})
    table: Dict[str, Any] = {
        "paper": False,
        "seed": 0,
        "checkpoint_every": 100,
        "target": {"size": 128, "polarity": "auto"},
        "model": {"family": "affine", "maps": int(maps), "parameterisation": "svd"},
        "renderer": {"supersample": 4, "sigma": 1.0},
    }
    renamed = {flags.get(k, k): v for k, v in config.items()}
    with _Inputs() as inputs:
        if isinstance(image, dict) or (
            isinstance(image, (str, os.PathLike))
            and (os.fspath(image).lower().endswith(".json") or not os.path.isfile(image))
        ):
            text, is_json = code_arg(image)
            if is_json:
                path = inputs.path("target_code.json")
                path.write_text(text)
                text = os.fspath(path)
            elif os.path.isfile(text):
                text = os.path.abspath(text)
            table["target"]["code"] = text
        else:
            table["target"]["image"] = inputs.picture(image)
        _merge(table, renamed)
        return run(table, output, progress=progress)


def fit_points(
    points: Any,
    k: int = 3,
    output: Optional[PathLike] = None,
    *,
    progress: Any = None,
    **config: Any,
) -> Result:
    """Fits an IFS of ``k`` similitudes to a point cloud by EM, as ``ifslab fit-points``
    does: ``points`` is an ``(N, H)`` array (any dimension H), a CSV or ``.npy`` file, or
    ``"ifs:NAME"`` (points drawn from a code). Other keys are a points config's
    (``depth=6``, ``pool=10``, ``runs=4``, ``seed=1``, ``paper=True``, …). The result's
    ``code`` is the fitted code (``code.json``), its ``log`` the fit's history."""
    with _Inputs() as inputs:
        if isinstance(points, str) and points.startswith("ifs:"):
            data = points
        elif isinstance(points, (str, os.PathLike)):
            data = os.path.abspath(os.fspath(points))
        else:
            a = np.asarray(points, dtype=np.float64)
            if a.ndim != 2:
                raise ValueError(f"points are an (N, H) array, got shape {a.shape}")
            path = inputs.path("points.npy")
            np.save(path, np.ascontiguousarray(a))
            data = os.fspath(path)
        table = _merge({"problem": "points", "data": data, "k": int(k)}, config)
        return run(table, output, progress=progress)


def sdf_fit(
    image: Any,
    pattern: str = "koch",
    output: Optional[PathLike] = None,
    *,
    progress: Any = None,
    **config: Any,
) -> Result:
    """Fits a segment pattern's control points to a silhouette or line picture with the
    differentiable SDF raster, as ``ifslab sdf fit`` does: ``image`` an array or a picture
    file, ``pattern`` a built-in pattern (``koch``, ``carpet``, ``carpet-square``) or a
    pattern file. Other keys are an SDF config's (``depth=5``, ``iterations=300``,
    ``paper=True``, …). The fitted pattern is ``result.file("pattern.json")``."""
    with _Inputs() as inputs:
        table = _merge(
            {"problem": "sdf", "target": inputs.picture(image), "pattern": os.fspath(pattern)},
            config,
        )
        return run(table, output, progress=progress)
