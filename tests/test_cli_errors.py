"""The command line shows one clear line and a non-zero exit for bad input, never a traceback."""

import subprocess
import sys

import pytest

from bayesmodal.cli import main


def _run(args, capsys):
    code = main(args)
    cap = capsys.readouterr()
    return code, cap.out, cap.err


@pytest.mark.parametrize(
    "content,pattern",
    [
        ("", "file is empty"),
        ("t,v,x1,x2,x3\n0,0,0,0,0\n0.1,0,0,0\n", "line 3 has 4 columns"),
        ("t,v,x1,x2,x3\n0,0,0,0,0\n0.1,nan,0,0,0\n0.2,0,0,0,0\n", "non-finite"),
        ("t,v,x1,x2,x3\n0,0,0,0,0\n0.1,0,0,0,0\n0.2,0,0,0,0\n", "input is all zeros"),
    ],
)
def test_lsq_bad_files_one_line_error(tmp_path, capsys, content, pattern):
    p = tmp_path / "bad.csv"
    p.write_text(content)
    code, out, err = _run(["lsq", str(p)], capsys)
    assert code == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("bayesmodal lsq: error:")
    assert pattern in lines[0]
    assert "Traceback" not in err


def test_wrong_number_of_outputs_is_named(tmp_path, capsys):
    p = tmp_path / "two.csv"
    rows = "\n".join(f"{0.01 * i},{1.0 if i < 3 else 0.0},{1e-3 * i},0" for i in range(20))
    p.write_text("t,v,x1,x2\n" + rows + "\n")
    code, _, err = _run(["lsq", str(p)], capsys)
    assert code == 2
    assert "2 outputs but the rig has 3 carts" in err


def test_debug_shows_traceback(tmp_path, capsys):
    p = tmp_path / "bad.csv"
    p.write_text("")
    code, _, err = _run(["--debug", "lsq", str(p)], capsys)
    assert code == 2
    assert "Traceback" in err


def test_console_script_exit_code(tmp_path):
    p = tmp_path / "missing.mat"
    r = subprocess.run([sys.executable, "-m", "bayesmodal", "lsq", str(p)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2
    assert "no such file" in r.stderr
    assert "Traceback" not in r.stderr


def test_console_script_usage_error_is_one_line():
    r = subprocess.run([sys.executable, "-m", "bayesmodal", "lsq", "--damping", "viscous",
                        "x.csv"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("bayesmodal lsq: error: argument --damping: invalid choice")
    assert "viscous" in lines[0] and lines[0].endswith("(see bayesmodal lsq --help)")
    # negative control: --help is not an error and prints the usage block
    r = subprocess.run([sys.executable, "-m", "bayesmodal", "lsq", "--help"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.startswith("usage: bayesmodal lsq")
