"""studies/orlov_grid.py without its runs: Orlov's cells, the spectrum's verdict on a
cvt_chain-like spectrum, and bad input."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "studies"))
import orlov_grid  # noqa: E402

#: a cvt_chain-like spectrum: real friction modes to -1e8, lightly damped oscillations
SPECTRUM = np.concatenate([-np.geomspace(1e2, 1.0e8, 50),
                           -2e3 + 1j * np.geomspace(2e4, 7e5, 20),
                           -2e3 - 1j * np.geomspace(2e4, 7e5, 20)])


def test_the_studys_grid_agrees_with_the_sources_page_and_runs_every_tested_cell():
    """The study's whole grid and the sources page's cells transcribe the same slides:
    every cell the page holds as tested has the study's verdict, every speed-up cell
    is a good one, and :func:`cells` runs every cell the page holds as tested."""
    from integrator_bench.harness.sources.numbers import ORLOV_SPEEDUPS, SLIDES_GRID

    tested = {c: v for c, v in SLIDES_GRID.items() if v != "untested"}
    assert tested and {c: orlov_grid.ORLOV_GRID.get(c) for c in tested} == tested
    assert all(orlov_grid.ORLOV_GRID[(k, h)] == "good" for k, h, _ in ORLOV_SPEEDUPS)
    assert set(tested) <= set(orlov_grid.cells())


def test_the_spectrum_tells_real_from_imaginary_extent():
    # P4 (beta 136.6) at 2e-6: h rho = 200 exceeds the real extent
    p4 = orlov_grid.spectrum_check(SPECTRUM, 4, 2e-6)
    assert p4["real"] > 1 and p4["worst"][1] == 0.0
    # P5 (beta 226.9) at 2e-6: the real extent holds
    assert orlov_grid.spectrum_check(SPECTRUM, 5, 2e-6)["real"] <= 1 + 1e-9
    # P9 (degree 81) at 4e-6: real modes inside, an oscillation outside the thin strip
    p9 = orlov_grid.spectrum_check(SPECTRUM, 9, 4e-6)
    assert p9["real"] <= 1 + 1e-9 and p9["complex"] > 1 and p9["worst"][1] != 0.0
    # the step along the whole spectrum never exceeds the real-axis one
    step = orlov_grid.spectrum_step(SPECTRUM, 9, 2 * 3266.0 / 1e8)
    assert 0 < step < 3266.0 / 1e8
    # a growing mode (positive real part) grows in the exact solution too: not a limit
    grown = np.append(SPECTRUM, 5.0)
    assert orlov_grid.spectrum_step(grown, 9, 2 * 3266.0 / 1e8) == step


def test_bad_input_is_one_line_and_exit_2():
    r = subprocess.run([sys.executable, str(ROOT / "studies" / "orlov_grid.py"), "--friction",
                        "3"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and r.stdout == ""
    assert r.stderr.strip().splitlines() == [
        "orlov_grid: error: --friction 3: valid are 1 (smooth) and 0 (linear)"]
