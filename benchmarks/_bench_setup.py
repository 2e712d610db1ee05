"""Shared fixture for the benchmarks: the ER32 + 7.94 mm end-mill assembly of the example setup."""

from __future__ import annotations

import statistics
import time

import numpy as np

from bayes_rcsa.model import Holder, HolderSegment, Material, PointReceptance, Tool, ToolPointModel, ToolSegment


def modal_spindle(frequency_hz: np.ndarray) -> PointReceptance:
    """A reciprocal, passive three-mode flange receptance (benchmark stand-in for a measured spindle)."""
    w = 2 * np.pi * frequency_hz
    block = np.zeros((w.size, 2, 2), complex)
    for fn, zeta, mass, ratio in [(700.0, 0.04, 8.0, 12.0), (1500.0, 0.03, 5.0, -20.0), (2600.0, 0.03, 4.0, 35.0)]:
        wn = 2 * np.pi * fn
        phi = np.array([1.0, ratio])
        block += np.outer(phi, phi)[None] / (mass * (wn**2 - w**2 + 2j * zeta * wn * w))[:, None, None]
    return PointReceptance(frequency_hz, block, "modal spindle")


def example_model() -> ToolPointModel:
    steel = Material(200e9, 7850.0, 0.29, 0.002, "steel")
    carbide = Material(580e9, 14500.0, 0.22, 0.001, "carbide")
    holder = Holder(steel, (HolderSegment(0.020, 0.063), HolderSegment(0.0595, 0.050, 0.00794)))
    tool = Tool(carbide, 0.1016, (ToolSegment(0.030, 0.00794, 0.8), ToolSegment(0.0716, 0.00794)))
    f = np.linspace(50.0, 6000.0, 2381)
    return ToolPointModel(holder, {"tool": tool}, {"x": modal_spindle(f)})


def median_time(fn, repeats: int = 7, number: int = 1) -> float:
    """Median wall time of ``fn()`` in seconds over ``repeats`` runs of ``number`` calls."""
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        for _ in range(number):
            fn()
        times.append((time.perf_counter() - t0) / number)
    return statistics.median(times)


def print_sbc_verdicts(names, check) -> None:
    """One line per ranked quantity of an SBC check (ECDF, Holm and chi-square p-values, verdict), then the total."""
    print(f"{'quantity':<18}{'ECDF p':>10}{'Holm p':>10}{'chi2 p':>10}  verdict")
    for n, p, h, c, ok in zip(names, check.p_ecdf, check.p_holm, check.p_chi2, check.passed):
        print(f"{n:<18}{p:>10.3f}{h:>10.3f}{c:>10.3f}  {'pass' if ok else 'FAIL'}")
    print(f"all pass at family-wise 0.01: {check.all_passed}")
