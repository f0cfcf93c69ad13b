"""Code files: what the library writes reads back to the same dict and the same bytes."""

import json

import numpy as np
import pytest

import ifslab
from conftest import cli_error_lines


def test_a_builtin_code_is_a_dict_in_the_file_format():
    fern = ifslab.code("fern")
    assert fern["format"] == "ifslab-code/1"
    assert fern["dim"] == 2
    assert len(fern["maps"]) == 4
    assert "fern" in ifslab.builtin_codes()


def test_a_code_saved_and_loaded_is_the_same_dict_to_the_bit(tmp_path):
    code = {
        "format": "ifslab-code/1",
        "name": "thirds",
        "dim": 2,
        "maps": [
            {"matrix": [[1 / 3, 0.1 + 0.2], [0.0, 1 / 3]], "offset": [np.pi / 10, -1e-17]},
            {"matrix": [[0.5, 0.0], [0.0, 0.5]], "offset": [0.5, 2 / 3]},
        ],
        "probabilities": [0.3, 0.7],
        "meta": {"note": "kept"},
    }
    path = tmp_path / "c.json"
    ifslab.save_code(code, path)
    back = ifslab.load_code(path)
    assert back == code
    # The numbers are the same floats, not merely close ones.
    assert back["maps"][0]["matrix"][0][1].hex() == (0.1 + 0.2).hex()


def test_files_the_command_line_writes_round_trip_byte_for_byte(cli, tmp_path):
    cli(["sample", "--maps", "4", "--count", "3", "--seed", "5", "-o", tmp_path / "codes"])
    files = sorted((tmp_path / "codes").glob("*.json"))
    assert len(files) == 3
    for f in files:
        again = tmp_path / ("again_" + f.name)
        ifslab.save_code(ifslab.load_code(f), again)
        assert again.read_bytes() == f.read_bytes(), f.name


def test_a_non_contractive_code_is_refused_with_the_command_lines_words(cli, tmp_path):
    code = ifslab.code("sierpinski")
    code["maps"][1]["matrix"] = [[1.5, 0.0], [0.0, 0.5]]
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(code))
    with pytest.raises(ifslab.IfslabError) as py:
        ifslab.render(path, size=32, points=1000)
    done = cli(["render", path, "--size", "32", "--points", "1000", "-o", tmp_path / "x.png"], check=False)
    assert done.returncode != 0
    lines = cli_error_lines(done.stderr)
    assert any("map 1" in l for l in lines), done.stderr
    for line in lines:
        assert line in str(py.value)
    # A dict is checked the same way, before anything runs.
    with pytest.raises(ifslab.IfslabError, match="map 1"):
        ifslab.render(code, size=32, points=1000)


def test_a_nan_in_a_code_file_is_refused_with_the_command_lines_words(cli, tmp_path):
    code = ifslab.code("sierpinski")
    code["maps"][0]["offset"][0] = float("nan")
    path = tmp_path / "nan.json"
    path.write_text(json.dumps(code))  # Python writes the token NaN, which JSON has not
    with pytest.raises(ifslab.IfslabError) as py:
        ifslab.load_code(path)
    done = cli(["render", path, "-o", tmp_path / "x.png"], check=False)
    assert done.returncode != 0
    for line in cli_error_lines(done.stderr):
        assert line in str(py.value)
    assert "nan.json" in str(py.value)


def test_a_missing_file_is_a_file_not_found_error_naming_it(cli, tmp_path):
    missing = "no/such/code.json"
    with pytest.raises(FileNotFoundError, match="no such file: `no/such/code.json`"):
        ifslab.render(missing, size=16, points=100)
    done = cli(["render", missing, "-o", tmp_path / "x.png"], check=False)
    assert "no such file: `no/such/code.json`" in done.stderr
    with pytest.raises(FileNotFoundError):
        ifslab.load_code(tmp_path / "absent.json")


def test_a_code_that_is_not_a_dict_or_a_name_is_a_type_error():
    with pytest.raises(TypeError):
        ifslab.render(42)
