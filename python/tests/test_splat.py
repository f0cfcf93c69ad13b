"""The splat's NumPy forward and vector–Jacobian product, checked against central finite
differences of the same call (same chaos-game seed) in f64."""

import numpy as np
import pytest

import ifslab
from ifslab import splat

MAPS = np.array(
    [
        [0.45, 0.1, -0.05, 0.5, -0.4, -0.3],
        [0.5, -0.12, 0.08, 0.42, 0.45, -0.2],
        [0.38, 0.05, 0.1, 0.4, 0.05, 0.5],
    ]
)
# 32 × 28, 2× supersampling, 24 trajectories of 100 kept points (as tests/renderer.rs).
SETTINGS = dict(size=(32, 28), supersample=2, sigma=1.3, trajectories=24, length=110, warmup=10, game={"start_half_width": 2.0})


def weights(shape):
    """Fixed pixel weights w: L = Σ w·image, so ∂L/∂image = w."""
    return np.sin(np.arange(np.prod(shape)) * 0.37 + 0.1).reshape(shape)


def loss(w, **kwargs):
    image, _ = splat.forward(seed=11, **SETTINGS, **kwargs)
    return float((w * image).sum())


def test_the_forward_pass_is_an_image_of_the_asked_size_and_repeatable():
    image, _ = splat.forward(MAPS, seed=11, **SETTINGS)
    assert image.shape == (28, 32) and image.dtype == np.float64
    assert 0.0 <= image.min() and image.max() <= 1.0 and image.max() > 0.2
    again, _ = splat.forward(MAPS, seed=11, **SETTINGS)
    np.testing.assert_array_equal(image, again)
    other, _ = splat.forward(MAPS, seed=11, draw=1, **SETTINGS)
    assert not np.array_equal(image, other)


def test_the_maps_vjp_matches_central_differences():
    w = weights((28, 32))
    image, tape = splat.forward(MAPS, seed=11, **SETTINGS)
    grad = splat.vjp(tape, w)
    assert grad.shape == (3, 6)
    h, tol, largest = 1e-7, 2e-4, 0.0
    for i in range(3):
        for k in range(6):
            up, down = MAPS.copy(), MAPS.copy()
            up[i, k] += h
            down[i, k] -= h
            fd = (loss(w, maps=up) - loss(w, maps=down)) / (2 * h)
            largest = max(largest, abs(fd))
            assert abs(fd - grad[i, k]) <= tol * (1 + abs(fd)), (i, k, grad[i, k], fd)
    # The loss does depend on the maps: the check is not of zeros against zeros.
    assert largest > 1.0


@pytest.mark.parametrize("param", ["svd", "naive"])
def test_the_theta_vjp_matches_central_differences(param):
    theta = splat.encode(MAPS, param)
    np.testing.assert_allclose(splat.decode(theta, param), MAPS, atol=1e-12)
    w = weights((28, 32))
    _, tape = splat.forward(theta=theta, param=param, seed=11, **SETTINGS)
    grad = splat.vjp(tape, w)
    assert grad.shape == theta.shape
    h, tol = 1e-7, 2e-4
    for k in range(theta.size):
        up, down = theta.copy(), theta.copy()
        up[k] += h
        down[k] -= h
        fd = (loss(w, theta=up, param=param) - loss(w, theta=down, param=param)) / (2 * h)
        assert abs(fd - grad[k]) <= tol * (1 + abs(fd)), (k, grad[k], fd)


def test_a_fixed_window_and_additive_blending_are_settings():
    image, tape = splat.forward(MAPS, seed=1, size=16, supersample=1, sigma=1.0, trajectories=10, length=50,
                                blend="additive", window=(-1.5, -1.5, 1.5, 1.5))
    assert image.shape == (16, 16)
    assert image.max() > 1.0  # density, not coverage
    assert splat.vjp(tape, np.ones_like(image)).shape == (3, 6)


def test_bad_settings_and_shapes_are_refused_with_the_librarys_words():
    with pytest.raises(ifslab.IfslabError, match="sigma"):
        splat.forward(MAPS, sigma=-1.0, size=8, trajectories=4, length=20)
    with pytest.raises(ifslab.IfslabError, match=r"\(n, 6\)"):
        splat.forward(np.zeros((3, 5)), size=8)
    with pytest.raises(ifslab.IfslabError, match="non-finite"):
        bad = MAPS.copy()
        bad[0, 0] = np.nan
        splat.forward(bad, size=8, trajectories=4, length=20)
    _, tape = splat.forward(MAPS, size=8, trajectories=4, length=20)
    with pytest.raises(ifslab.IfslabError, match="shape"):
        splat.vjp(tape, np.zeros((4, 4)))
