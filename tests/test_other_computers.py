"""The same answer on another computer: the case study and two machine reports regenerated
under other OpenBLAS kernels and thread counts give the same bytes.

A new processor changes the last bits of every matrix product (another SIMD kernel, another
summation order); ``OPENBLAS_CORETYPE`` makes this machine's OpenBLAS use another
processor's kernels, and ``OPENBLAS_NUM_THREADS`` another split of the work. Each run is a
fresh process, and each checks that OpenBLAS reports the kernel it was asked for, so the
test cannot pass by running the same arithmetic twice.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).parent.parent
FIGURES = ROOT / "figures"
#: Kernels a processor with AVX2 (Haswell) or AVX (Sandybridge) can run, by the CPU flag
#: they need.
KERNELS = {"Haswell": "avx2", "Sandybridge": "avx"}
#: The files compared byte for byte: tables, markdown, JSON (and, between kernels on one
#: computer, report.html, whose pictures then come from the same matplotlib).
TEXT_SUFFIXES = (".csv", ".md", ".json")


def _cpu_flags() -> set[str]:
    try:
        text = Path("/proc/cpuinfo").read_text()
    except OSError:
        return set()
    lines = [line for line in text.splitlines() if line.startswith("flags")]
    return set(lines[0].split(":", 1)[1].split()) if lines else set()


def _environment(kernel: str | None, threads: int) -> dict:
    env = {key: value for key, value in os.environ.items()
           if key not in ("OPENBLAS_CORETYPE", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    env["OPENBLAS_NUM_THREADS"] = str(threads)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), env.get("PYTHONPATH", "")])
    if kernel is not None:
        env["OPENBLAS_CORETYPE"] = kernel
    return env


def _openblas(env) -> dict:
    """What OpenBLAS reports in a process with ``env``: its kernel and thread count."""
    code = ("import json, numpy, threadpoolctl; print(json.dumps([i for i in "
            "threadpoolctl.threadpool_info() if i['internal_api'] == 'openblas']))")
    found = json.loads(subprocess.run([sys.executable, "-c", code], env=env, check=True,
                                      capture_output=True, text=True).stdout)
    if not found:
        pytest.skip("numpy does not use OpenBLAS here, so its kernel cannot be chosen")
    return found[0]


def _configuration(kernel: str | None, threads: int) -> dict:
    """The environment of a run, after checking OpenBLAS takes it."""
    if kernel is not None and KERNELS[kernel] not in _cpu_flags():
        pytest.skip(f"this processor lacks {KERNELS[kernel]}, which the {kernel} kernel needs")
    env = _environment(kernel, threads)
    info = _openblas(env)
    if kernel is not None:
        assert info["architecture"].lower() == kernel.lower(), info
    assert info["num_threads"] == threads, info
    return env


def _run(arguments, env):
    done = subprocess.run([sys.executable, *arguments], env=env, cwd=ROOT,
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr[-3000:]


def _differing(folder: Path, other: Path, suffixes=TEXT_SUFFIXES) -> list[str]:
    """Files of either folder (with these suffixes) missing from the other or differing."""
    def files(root):
        return {str(p.relative_to(root)) for p in root.rglob("*") if p.suffix in suffixes}

    names = files(folder) | files(other)
    return sorted(name for name in names
                  if not (folder / name).is_file() or not (other / name).is_file()
                  or (folder / name).read_bytes() != (other / name).read_bytes())


CASE_STUDY = [pytest.param(None, 2, id="own kernel, 2 threads"),
              pytest.param("Haswell", 1, id="Haswell, 1 thread"),
              pytest.param("Sandybridge", 1, id="Sandybridge, 1 thread")]


@pytest.mark.parametrize("kernel, threads", CASE_STUDY)
def test_case_study_regenerates_figures_under_another_kernel(kernel, threads, tmp_path):
    """The README's first command under another kernel or thread count writes the committed
    tables, markdown and JSON of ``figures/`` byte for byte (the own kernel on one thread is
    ``test_reproduce``'s run)."""
    env = _configuration(kernel, threads)
    _run(["-m", "studies.reproduce_paper", "--out", str(tmp_path), "--seed", "2023",
          "--quiet"], env)
    assert _differing(tmp_path, FIGURES) == []


#: Every section, on smaller Monte-Carlo samples (the bytes compared do not need more).
SMALL_REPORT = ("--repeats", "2", "--samples", "2000", "--machines", "500")
REPORTS = [pytest.param(["docs/examples/gantry5.toml"], id="gantry5"),
           pytest.param(["tests/machines/swivel5_zone.toml", "--workspace", "grid"],
                        id="swivel5 with its zone, grid")]


@pytest.mark.parametrize("arguments", REPORTS)
def test_report_is_the_same_under_three_kernels(arguments, tmp_path):
    """``precrel report`` under the own kernel (two threads), Haswell and Sandybridge (one
    thread each) writes the same report: tables, markdown, JSON and report.html."""
    folders = []
    for kernel, threads in ((None, 2), ("Haswell", 1), ("Sandybridge", 1)):
        env = _configuration(kernel, threads)
        folder = tmp_path / (kernel or "own")
        _run(["-m", "studies", "report", *arguments, *SMALL_REPORT, "--out", str(folder),
              "--quiet"], env)
        folders.append(folder)
    for other in folders[1:]:
        assert _differing(folders[0], other, TEXT_SUFFIXES + (".html",)) == [], other.name
