"""The command line, called in-process through main()."""

import subprocess
import sys

from qdrefine.cli import main


def test_demo_prints_a_summary(capsys):
    assert main(["demo", "--levels", "1"]) == 0
    out = capsys.readouterr().out
    for scheme in ("7t-qd", "7t-le", "7t-d", "4t-le", "4t-red"):
        assert scheme in out
    assert "NO" not in out


def test_python_dash_m_runs():
    result = subprocess.run([sys.executable, "-m", "qdrefine", "--help"], capture_output=True,
                            text=True, check=False)
    assert result.returncode == 0
    assert "demo" in result.stdout
