"""The evaluation renderer from Python draws what `ifslab render` draws."""

import numpy as np
import pytest

import ifslab


def test_the_image_has_the_asked_shape_and_values_in_the_unit_interval():
    image = ifslab.render("sierpinski", size=(64, 48), points=200_000)
    assert image.shape == (48, 64)
    assert image.dtype == np.float32
    assert image.min() == 0.0 and image.max() == 1.0
    # Coverage: the triangle covers some of the window, not all of it.
    assert 0.05 < image.mean() < 0.9


@pytest.mark.parametrize(
    "code, options, flags",
    [
        ("fern", {}, []),
        ("fern", {"supersample": 4}, ["--supersample", "4"]),
        ("fern", {"density": True}, ["--density"]),
        # Deep zoom through the code's words, as `render --zoom` draws it, at a vertex.
        ("sierpinski", {"zoom": 1024, "center": (0.5, 0.0)}, ["--zoom", "1024", "--center", "0.5,0"]),
        ("sierpinski", {"zoom": 8, "center": (0.25, 0.1), "plain_zoom": True}, ["--zoom", "8", "--center", "0.25,0.1", "--plain-zoom"]),
    ],
)
def test_the_render_equals_the_command_lines_png(cli, tmp_path, code, options, flags):
    png = tmp_path / "cli.png"
    cli(["render", code, "--size", "96", "--points", "300000", "--seed", "3", "-o", png, *flags])
    image = ifslab.render(code, size=96, points=300_000, seed=3, **options)
    from_cli = ifslab.load_image(png)
    assert from_cli.shape == image.shape
    # The PNG holds round(255 v).
    np.testing.assert_array_equal(np.round(image * 255) / 255, np.round(from_cli * 255) / 255)
    assert image.max() > 0


def test_a_code_dict_a_file_and_a_name_render_the_same(tmp_path):
    path = tmp_path / "fern.json"
    ifslab.save_code("fern", path)
    by_name = ifslab.render("fern", size=32, points=50_000)
    np.testing.assert_array_equal(by_name, ifslab.render(path, size=32, points=50_000))
    np.testing.assert_array_equal(by_name, ifslab.render(ifslab.load_code(path), size=32, points=50_000))


def test_a_zoom_at_two_to_the_twenty_still_finds_points():
    image, stats = ifslab.render_with_stats(
        "sierpinski", size=64, points=500_000, zoom=2.0**20, center=(0.5, 0.0)
    )
    assert stats["points_in_window"] > 100_000
    assert image.mean() > 0.05


def test_a_window_beside_the_attractor_is_an_error_unless_allowed():
    with pytest.raises(ifslab.IfslabError, match="none of the .* points landed in the window"):
        ifslab.render("sierpinski", size=32, points=10_000, zoom=64, center=(50.0, 50.0), plain_zoom=True)
    empty = ifslab.render(
        "sierpinski", size=32, points=10_000, zoom=64, center=(50.0, 50.0), plain_zoom=True, allow_empty=True
    )
    assert empty.shape == (32, 32) and empty.max() == 0.0


def test_progress_reaches_the_callback():
    events = []
    _, stats = ifslab.render_with_stats(
        "fern", size=64, points=2_000_000, progress=lambda e, v: events.append((e, v))
    )
    assert events[0] == ("length", 2_000_000)
    positions = [v for e, v in events if e == "position"]
    assert positions == sorted(positions)
    # The last position is reported however soon it follows the one before.
    assert positions[-1] == stats["points_generated"] >= 2_000_000


def test_an_exception_in_the_callback_is_raised_after_the_render():
    def boom(event, value):
        raise ValueError("from the callback")

    with pytest.raises(ValueError, match="from the callback"):
        ifslab.render("fern", size=32, points=100_000, progress=boom)


def test_progress_true_draws_a_tqdm_bar_where_tqdm_is_installed(monkeypatch):
    """With a stand-in tqdm module: the bar gets the render's length, reaches its points
    and is closed when the render returns."""
    import sys
    import types

    bars = []

    class Bar:
        def __init__(self, total=None, **kwargs):
            self.total, self.n, self.closed = total, 0, False
            bars.append(self)

        def update(self, k):
            self.n += k

        def refresh(self):
            pass

        def set_postfix_str(self, s):
            pass

        def close(self):
            self.closed = True

    tqdm = types.ModuleType("tqdm")
    auto = types.ModuleType("tqdm.auto")
    auto.tqdm = Bar
    tqdm.auto = auto
    monkeypatch.setitem(sys.modules, "tqdm", tqdm)
    monkeypatch.setitem(sys.modules, "tqdm.auto", auto)
    _, stats = ifslab.render_with_stats("fern", size=32, points=1_000_000, progress=True)
    assert len(bars) == 1
    assert bars[0].total == 1_000_000
    assert bars[0].n == stats["points_generated"]
    assert bars[0].closed


@pytest.mark.parametrize(
    "options, words",
    [
        ({"zoom": float("nan")}, "invalid parameter `zoom`: factor must be finite and > 0, got NaN"),
        ({"center": (float("nan"), 0.0)}, "invalid parameter `center`: must be finite"),
        ({"zoom": 1e300}, "past double precision"),
    ],
)
def test_a_nan_or_impossible_zoom_is_refused_with_the_librarys_words(options, words):
    with pytest.raises(ifslab.IfslabError) as e:
        ifslab.render("fern", size=16, points=1000, **options)
    assert words in str(e.value)
