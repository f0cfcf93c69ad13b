"""Runs from Python go through the same run API as the command line: same folders, same
results for the same config and seed."""

import json

import numpy as np
import pytest

import ifslab
from conftest import cli_error_lines, without_seconds

# A short inversion (the default recipe, few iterations) that still runs every stage:
# collage start, hybrid with an annealing phase, checkpoints, renders, zoom strip, summary.
SHORT = dict(size=48, iterations=12, checkpoint_every=5, strategy={"kind": "cold_hybrid", "anneal_every": 6})
FAST = dict(size=32, iterations=8, init="em")
SHORT_FLAGS = ["--size", "48", "--iters", "12", "--checkpoint-every", "5", "--strategy", "hybrid", "--anneal-every", "6"]


@pytest.fixture(scope="module")
def sierpinski_png(tmp_path_factory):
    path = tmp_path_factory.mktemp("target") / "sierpinski.png"
    ifslab.save_image(ifslab.render("sierpinski", size=96, points=2_000_000), path)
    return path


def test_an_inversion_from_an_array_writes_the_run_folder_and_reads_it_back(tmp_path):
    image = ifslab.render("sierpinski", size=96, points=2_000_000)
    result = ifslab.invert(image, maps=3, output=tmp_path / "run", **SHORT)
    assert result.problem == "image"
    assert len(result.code["maps"]) == 3
    assert result.summary["iterations"] == 12
    assert len(result.log["loss"]) == 12
    assert np.all(np.isfinite(result.log["loss"]))
    for name in ("config.toml", "summary.json", "log.csv", "code.json", "render.png", "zoom_strip.png"):
        assert (tmp_path / "run" / name).is_file(), name
    assert result.config["model"]["maps"] == 3
    assert result.image("render.png").ndim == 2
    # Its code renders like any other.
    assert ifslab.render(result, size=32, points=100_000).max() == 1.0


def test_an_inversion_equals_the_command_lines_for_the_same_flags(cli, tmp_path, sierpinski_png):
    cli(["invert", sierpinski_png, "--maps", "3", *SHORT_FLAGS, "-o", tmp_path / "cli"])
    result = ifslab.invert(sierpinski_png, maps=3, output=tmp_path / "py", **SHORT)
    assert (tmp_path / "py" / "code.json").read_bytes() == (tmp_path / "cli" / "code.json").read_bytes()
    assert without_seconds(tmp_path / "py" / "log.csv") == without_seconds(tmp_path / "cli" / "log.csv")
    theirs = ifslab.load_run(tmp_path / "cli")
    assert theirs.code == result.code
    assert theirs.summary["final_loss"] == result.summary["final_loss"]
    assert theirs.summary["iou"] == result.summary["iou"]
    ours, theirs = result.config, theirs.config
    for c in (ours, theirs):
        c.pop("output", None)
    assert ours == theirs


def test_without_an_output_folder_the_run_goes_to_a_temporary_one():
    image = ifslab.render("sierpinski", size=64, points=500_000)
    result = ifslab.invert(image, maps=3, **FAST)
    assert result.dir.is_dir() and (result.dir / "summary.json").is_file()


def test_a_config_dict_and_a_toml_file_run_alike(tmp_path, repo):
    config = {
        "problem": "points",
        "data": "ifs:sierpinski",
        "points": 4000,
        "k": 3,
        "depth": 4,
        "pool": 4,
        "runs": 1,
        "seed": 1,
    }
    a = ifslab.run(config, tmp_path / "a")
    toml = tmp_path / "points.toml"
    toml.write_text("\n".join(f"{k} = {json.dumps(v)}" for k, v in config.items() if k != "seed") + "\n")
    b = ifslab.run(toml, tmp_path / "b", set={"seed": 1})
    assert a.code == b.code
    assert a.problem == b.problem == "points"


def test_fit_points_recovers_the_sierpinski_triangle_from_an_array(tmp_path):
    rng = np.random.default_rng(0)
    corners = np.array([[0.0, 0.0], [1.0, 0.0], [0.5, np.sqrt(3) / 2]])
    x = np.zeros(2)
    points = []
    for i in range(6000):
        x = (x + corners[rng.integers(3)]) / 2
        if i >= 20:
            points.append(x)
    result = ifslab.fit_points(np.array(points), k=3, depth=5, pool=6, runs=2, seed=0, output=tmp_path / "em")
    maps = result.code["maps"]
    assert len(maps) == 3
    scales = sorted(abs(np.linalg.det(np.array(m["matrix"]))) ** 0.5 for m in maps)
    np.testing.assert_allclose(scales, [0.5, 0.5, 0.5], atol=0.05)


def test_a_bad_config_key_is_refused_with_the_librarys_words(cli, tmp_path):
    with pytest.raises(ifslab.IfslabError) as py:
        ifslab.run({"problem": "points", "data": "ifs:fern", "kk": 3}, tmp_path / "x")
    toml = tmp_path / "bad.toml"
    toml.write_text('problem = "points"\ndata = "ifs:fern"\nkk = 3\n')
    done = cli(["run", toml, "-o", tmp_path / "y"], check=False)
    assert done.returncode != 0
    # The file's name differs (a dict has none); the library's complaint is the same.
    complaint = [l for l in cli_error_lines(done.stderr) if "unknown field `kk`" in l]
    assert complaint, done.stderr
    assert complaint[0] in str(py.value)


def test_a_missing_picture_is_a_file_not_found_error(tmp_path):
    with pytest.raises((FileNotFoundError, ifslab.IfslabError), match="missing.png"):
        ifslab.invert(tmp_path / "missing.png", maps=3, output=tmp_path / "r")


def test_a_folder_holding_a_run_is_refused(tmp_path, repo):
    tiny = dict(iterations=2, checkpoint_every=1, flames=[{"xforms": 2, "variations": ["linear"]}], sampler={"size": 16, "trajectories": 20, "steps": 50})
    ifslab.flame.learn(repo / "data" / "paintings" / "circles3.png", output=tmp_path / "r", **tiny)
    with pytest.raises(ifslab.IfslabError, match="already holds a run"):
        ifslab.flame.learn(repo / "data" / "paintings" / "circles3.png", output=tmp_path / "r", **tiny)


def test_sdf_fit_recovers_a_pattern_from_its_picture(tmp_path, repo):
    result = ifslab.sdf_fit(repo / "data" / "sdf" / "koch_128.png", pattern="koch", depth=4, iterations=40, output=tmp_path / "sdf")
    assert result.problem == "sdf"
    assert (tmp_path / "sdf" / "pattern.json").is_file()
    assert len(result.log["loss"]) == 40
    assert result.log["loss"][-1] < result.log["loss"][0]


def test_a_flame_renders_as_the_command_line_draws_it(cli, tmp_path, repo):
    path = repo / "tests" / "fixtures" / "flame" / "images" / "f00.flame"
    image = ifslab.flame.render(path, size=(48, 32), quality=5, seed=2)
    assert image.shape == (32, 48, 4)
    assert image.dtype == np.float32
    # The library's scale: RGB in [0, 255], alpha in [0, 1].
    assert 0.0 <= image.min() and image[..., :3].max() <= 255.0 and image[..., 3].max() <= 1.0
    assert image[..., :3].std() > 0
    png = tmp_path / "f00.png"
    cli(["flame", "render", path, "--size", "48", "32", "--quality", "5", "--seed", "2", "-o", png])
    from_cli = np.round(ifslab.load_image(png, rgb=True) * 255).astype(np.uint8)
    np.testing.assert_array_equal(image[..., :3].astype(np.uint8), from_cli)


def test_a_flame_given_as_text_renders_like_its_file(repo):
    path = repo / "tests" / "fixtures" / "flame" / "images" / "f00.flame"
    a = ifslab.flame.render(path, size=(32, 32), quality=3)
    b = ifslab.flame.render(path.read_text(), size=(32, 32), quality=3)
    np.testing.assert_array_equal(a, b)


def test_a_flame_is_learned_from_a_picture(tmp_path, repo):
    result = ifslab.flame.learn(
        repo / "data" / "paintings" / "circles3.png",
        output=tmp_path / "flame",
        iterations=4,
        flames=[{"xforms": 4, "variations": ["linear"]}],
        sampler={"size": 32, "trajectories": 100, "steps": 100},
    )
    assert result.problem == "flame"
    assert (tmp_path / "flame" / "learned.flame").is_file()
    rendered = ifslab.flame.render(tmp_path / "flame" / "learned.flame", size=(24, 24), quality=2)
    assert rendered.shape == (24, 24, 4)


def test_a_multi_view_run_goes_through_the_same_config(tmp_path, repo):
    # problem = "image3d" as a dict: the shipped tetrahedron views, a short fit.
    config = {
        "problem": "image3d",
        "views": str(repo / "data" / "views" / "tetrahedron"),
        "truth": "tetrahedron",
        "maps": 4,
        "iterations": 6,
        "ink": 0.0,
        "render": {"supersample": 1, "sigma_final": 0.8, "trajectories": 40},
    }
    result = ifslab.run(config, tmp_path / "tet")
    assert result.problem == "image3d"
    assert result.summary["iterations"] == 6
    assert result.summary["fit"]["voxel_iou"] > 0.0
    assert (tmp_path / "tet" / "points.ply").is_file()
    assert ifslab.resolve_config(config)["views"].endswith("tetrahedron")
