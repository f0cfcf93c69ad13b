"""The splat as a torch.autograd.Function (only where torch is installed; CI does not
install it, and the NumPy pair it wraps is tested in test_splat.py)."""

import numpy as np
import pytest

torch = pytest.importorskip("torch")

import ifslab.torch  # noqa: E402
from ifslab import splat  # noqa: E402

from test_splat import MAPS, SETTINGS, weights  # noqa: E402


def test_autograd_gives_the_splats_vjp():
    maps = torch.tensor(MAPS, dtype=torch.float64, requires_grad=True)
    image = ifslab.torch.splat(maps, seed=11, **SETTINGS)
    w = torch.tensor(weights(tuple(image.shape)))
    (w * image).sum().backward()
    _, tape = splat.forward(MAPS, seed=11, **SETTINGS)
    np.testing.assert_allclose(maps.grad.numpy(), splat.vjp(tape, w.numpy()), rtol=1e-12, atol=1e-12)


def test_gradcheck_at_a_fixed_seed():
    maps = torch.tensor(MAPS, dtype=torch.float64, requires_grad=True)
    f = lambda m: ifslab.torch.splat(m, seed=11, **SETTINGS)  # noqa: E731
    assert torch.autograd.gradcheck(f, (maps,), eps=1e-7, atol=1e-3, rtol=1e-3)
