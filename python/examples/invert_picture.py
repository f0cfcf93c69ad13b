"""Load a picture, recover an IFS code from it, plot the loss and a zoom strip — what a
notebook would do with ifslab.

    pip install ./python matplotlib
    python python/examples/invert_picture.py                       # a fern drawn for the purpose
    python python/examples/invert_picture.py my_picture.png --maps 4 --iterations 1000

Without matplotlib it prints what it would have plotted and writes nothing else.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import ifslab


def fixed_point(m: dict) -> np.ndarray:
    """The fixed point of one map x ↦ Mx + b: a point of the attractor, so a zoom centred
    there never misses it."""
    a, b = np.array(m["matrix"]), np.array(m["offset"])
    return np.linalg.solve(np.eye(len(b)) - a, b)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("picture", nargs="?", help="a PNG or JPEG (default: a fern rendered here)")
    parser.add_argument("--maps", type=int, default=4, help="maps of the code to recover")
    parser.add_argument("--iterations", type=int, default=300, help="optimisation iterations")
    parser.add_argument("--size", type=int, default=128, help="side of the fitted target in pixels")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("-o", "--output", type=Path, help="run folder (default: a temporary one)")
    parser.add_argument("--plot", type=Path, default=Path("invert_picture.png"), help="where the figure goes")
    args = parser.parse_args()

    if args.picture:
        picture = ifslab.load_image(args.picture)
    else:
        picture = ifslab.render("fern", size=256, points=5_000_000)
    print(f"picture: {picture.shape[1]}×{picture.shape[0]}")

    result = ifslab.invert(
        picture,
        maps=args.maps,
        size=args.size,
        iterations=args.iterations,
        seed=args.seed,
        output=args.output,
        progress=True,  # a tqdm bar where tqdm is installed
    )
    print(result.headline)
    print(f"run folder: {result.dir}")

    loss = result.log["loss"]
    centre = fixed_point(result.code["maps"][0])
    zooms = [1, 4, 16, 64]
    strip = [ifslab.render(result, size=256, points=5_000_000, zoom=z, center=centre) for z in zooms]

    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: loss {loss[0]:.4f} → {loss[-1]:.4f} over {len(loss)} iterations; "
              f"zoom strip at {zooms} around {centre} not drawn")
        return

    fig = plt.figure(figsize=(12, 6))
    grid = fig.add_gridspec(2, len(zooms) + 1)
    ax = fig.add_subplot(grid[0, 0])
    ax.imshow(picture, cmap="gray")
    ax.set_title("picture")
    ax.axis("off")
    ax = fig.add_subplot(grid[0, 1:])
    ax.plot(result.log["iter"], loss)
    ax.set_yscale("log")
    ax.set_xlabel("iteration")
    ax.set_ylabel("loss")
    for i, (z, image) in enumerate(zip(zooms, strip)):
        ax = fig.add_subplot(grid[1, i + 1])
        ax.imshow(image, cmap="gray")
        ax.set_title(f"{z}×")
        ax.axis("off")
    ax = fig.add_subplot(grid[1, 0])
    ax.imshow(result.image("render.png"), cmap="gray")
    ax.set_title("recovered")
    ax.axis("off")
    fig.tight_layout()
    fig.savefig(args.plot, dpi=100)
    print(f"figure: {args.plot}")


if __name__ == "__main__":
    main()
