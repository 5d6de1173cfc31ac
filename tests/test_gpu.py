"""The GPU path (:mod:`qdrefine.gpu`) against the CPU path, bit for bit.

The cases live in ``gpu_cases.py`` and run in a child pytest process, because numba picks
the CUDA simulator or the real target once, when ``numba.cuda`` is first imported: under
the simulator (``NUMBA_ENABLE_CUDASIM=1``) always, and on the real target too when this
machine has a CUDA GPU. Nothing in this process touches ``numba.cuda``, so the other test
modules are unaffected.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).parent
SIMULATOR = "NUMBA_ENABLE_CUDASIM"


def _gpu_present() -> bool:
    """Whether numba's real CUDA target finds a device (asked in a child process)."""
    env = {k: v for k, v in os.environ.items() if k != SIMULATOR}
    probe = subprocess.run(
        [sys.executable, "-c", "from numba import cuda; print(cuda.is_available())"],
        env=env, capture_output=True, text=True, timeout=120)
    return probe.stdout.strip().endswith("True")


TARGETS = ["simulator"] + (["gpu"] if _gpu_present() else [])


@pytest.mark.parametrize("target", TARGETS)
def test_gpu_path_matches_the_cpu_path(target):
    env = {k: v for k, v in os.environ.items() if k != SIMULATOR}
    if target == "simulator":
        env[SIMULATOR] = "1"
    run = subprocess.run(
        [sys.executable, "-m", "pytest", "-o", "addopts=", "-q", "-p", "no:cacheprovider",
         str(HERE / "gpu_cases.py")],
        cwd=HERE.parent, env=env, capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, f"gpu_cases.py on the {target}:\n{run.stdout[-6000:]}" \
                                f"\n{run.stderr[-2000:]}"
    assert " passed" in run.stdout and " failed" not in run.stdout


def test_without_the_simulator_a_missing_gpu_is_one_clear_error():
    """Off the simulator: refined on a GPU when there is one, else one ``RuntimeError``
    line saying so."""
    env = {k: v for k, v in os.environ.items() if k != SIMULATOR}
    code = ("from qdrefine import examples, refine, get_scheme\n"
            "from qdrefine.gpu import check_device_memory\n"
            "from qdrefine.gpu.refine import pass_times\n"
            "mesh = examples.square(1)\n"
            "for call in (lambda: refine(mesh, device='cuda').n_triangles,\n"
            "             lambda: pass_times(mesh.points, mesh.triangles) and 14,\n"
            "             lambda: check_device_memory(4, 2, get_scheme('7t-qd'), 1, False)\n"
            "             or 14):\n"
            "    try:\n"
            "        print(call())\n"
            "    except RuntimeError as exc:\n"
            "        print('RuntimeError:', exc)\n")
    run = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    lines = run.stdout.splitlines()
    assert len(lines) == 3, run.stdout  # one line each (numba's error has several)
    for line in lines:
        if "gpu" in TARGETS:
            assert line == "14"
        else:
            assert line.startswith("RuntimeError: device='cuda': no CUDA GPU is available")


def test_importing_qdrefine_does_not_import_the_cuda_target():
    """The GPU extra stays optional: ``import qdrefine`` and CPU refinement never load
    ``numba.cuda``."""
    code = ("import sys\nfrom qdrefine import examples, refine\nrefine(examples.square(1))\n"
            "print(sorted(m for m in sys.modules if m.startswith(('numba.cuda', 'qdrefine.gpu'))))")
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300)
    assert run.returncode == 0, run.stderr[-2000:]
    assert run.stdout.strip() == "[]"
