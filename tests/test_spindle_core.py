"""Spindle identification building blocks: inverse coupling, rotations, noise, modal model, samples, parsing.

The round trip forward-couples a flange block to the artifact with the
model's generic coupling functions (``attach`` and explicit rigid-coupling
formulas written here), independently of ``bayes_rcsa.spindle.inverse``.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from bayes_rcsa.errors import DataError, SetupError
from bayes_rcsa.model import Holder, HolderSegment, Material, PointReceptance, Tool, ToolSegment, attach
from bayes_rcsa.model import Configuration, ToolPointModel, free_free_receptances, inv2
from bayes_rcsa.model.timoshenko import Segment
from bayes_rcsa.spindle.artifact import Artifact
from bayes_rcsa.spindle.inverse import forward_artifact, inverse_exact, unreliable_bands
from bayes_rcsa.spindle.noise import estimate_relative_noise
from bayes_rcsa.spindle.rotations import finite_difference_block, free_end_block
from bayes_rcsa.spindle.smoothing import ModalModel, is_passive, is_reciprocal, passivity_margin
from bayes_rcsa.spindle.substructure import artifact_receptances
from bayes_rcsa.spindle.uncertainty import SpindleSamples, assign_samples, load_spindle_samples, save_spindle_samples

STEEL = Material(200e9, 7850.0, 0.29, 0.002, name="steel")
F = np.arange(200.0, 4001.0, 10.0)


def artifact(point2: float = 0.1716) -> Artifact:
    holder = Holder(STEEL, (HolderSegment(0.020, 0.063), HolderSegment(0.0316, 0.044), HolderSegment(0.050, 0.040, 0.020)))
    blank = Tool(STEEL, 0.125, (ToolSegment(0.125, 0.020),), name="blank")
    return Artifact(holder, blank, 0.045, (0.0, point2))


def spindle_block(f: np.ndarray) -> np.ndarray:
    """A passive, reciprocal flange block with two modes (a stand-in spindle), shape (n, 2, 2)."""
    w = 2 * np.pi * f
    out = np.zeros((f.size, 2, 2), dtype=complex)
    for fr, zeta, phi in ((660.0, 0.03, (2.0e-4, 1.5e-3)), (1900.0, 0.01, (1.0e-4, 3.0e-3))):
        wr = 2 * np.pi * fr
        q = 1.0 / (wr**2 - w**2 + 2j * zeta * wr * w)
        out += q[:, None, None] * np.outer(phi, phi) * wr**2
    return out


def reference_assembly(art: Artifact, s: np.ndarray, f: np.ndarray) -> np.ndarray:
    """H11, H12, H22 of spindle + artifact by substructure coupling (point 1 = free end).

    Beam a: flange -> point 2, beam b: point 2 -> free end.  The spindle is
    attached to beam a (``attach``), which gives the point receptance P at
    point 2; joining beam b there rigidly::

        H22 = P (P + B11)^-1 B11,  H12 = B21 (P + B11)^-1 P,  H11 = B22 - B21 (P + B11)^-1 B12
    """
    w = 2 * np.pi * f
    segs = art.segments()
    z2 = art.point_positions()[1]
    a_segs, b_segs, pos = [], [], 0.0
    for seg in segs:
        lo, hi = pos, pos + seg.length
        if hi <= z2 + 1e-12:
            a_segs.append(seg)
        elif lo >= z2 - 1e-12:
            b_segs.append(seg)
        else:
            a_segs.append(Segment(z2 - lo, seg.section))
            b_segs.append(Segment(hi - z2, seg.section))
        pos = hi
    p = attach(s, free_free_receptances(a_segs, w))
    b = free_free_receptances(b_segs, w)
    d = inv2(p + b.r11)
    h22 = (p @ d @ b.r11)[:, 0, 0]
    h12 = (b.r21 @ d @ p)[:, 0, 0]
    h11 = (b.r22 - b.r21 @ d @ b.r12)[:, 0, 0]
    return np.stack([h11, h12, h22], axis=-1)


# ------------------------------------------------------------ inversion --


def test_noise_free_round_trip_recovers_the_flange_block():
    """Forward-couple S to the artifact (independent coupling code), invert: S back to 1e-9."""
    art = artifact()
    s = spindle_block(F)
    g = reference_assembly(art, s, F)
    ar = artifact_receptances(art, 2 * np.pi * F)
    # the spindle package's own forward model agrees with the reference coupling
    np.testing.assert_allclose(forward_artifact(s, ar), g, rtol=1e-9, atol=0)
    back = inverse_exact(ar, g).block
    scale = np.abs(s).max(axis=0)  # per entry; h, l, p differ by orders of magnitude
    assert np.max(np.abs(back - s) / scale) < 1e-9
    assert np.array_equal(back[:, 0, 1], back[:, 1, 0])


def test_coinciding_points_are_rejected():
    with pytest.raises(SetupError, match="coincide"):
        artifact(point2=0.0)


def test_exact_free_end_block_and_finite_difference_bias():
    """Exact rotations reproduce the coupled block; finite differences are biased whatever the spacing.

    The finite difference of u is the slope du/dz, but the coupling's rotation
    is the Timoshenko section rotation psi; they differ by the shear angle
    (about 7 % of N11 at 1 kHz for the 20 mm blank), which does not vanish as
    the spacing shrinks, while the truncation error grows with it.
    """
    s = spindle_block(F)
    i = int(np.argmin(np.abs(F - 1000.0)))
    errors = {}
    for sep in (0.0025, 0.005, 0.040):
        art = artifact(point2=sep)
        ar = artifact_receptances(art, 2 * np.pi * F)
        g11 = free_end_block(ar, inv2(ar.block("f", "f") + s))
        g = reference_assembly(art, s, F)
        # the exact block's (0, 0) entry is the measured H11 of the independent coupling
        np.testing.assert_allclose(g11[:, 0, 0], g[:, 0], rtol=1e-9)
        fd = finite_difference_block(g[:, 0], g[:, 1], g[:, 1], g[:, 2], separation=sep)
        errors[sep] = abs(fd[i, 1, 0] - g11[i, 1, 0]) / abs(g11[i, 1, 0])
    # shear floor: halving a small spacing barely changes the error (5-10 % here)
    assert 0.05 < errors[0.0025] < 0.15 and abs(errors[0.0025] / errors[0.005] - 1) < 0.2
    assert errors[0.040] > 0.1  # truncation at a wide spacing


def test_finite_differences_need_distinct_points():
    with pytest.raises(SetupError):
        finite_difference_block(np.ones(3), np.ones(3), np.ones(3), np.ones(3), 0.0)


def test_unreliable_bands_are_contiguous_runs():
    f = np.arange(10.0)
    flags = np.array([0, 1, 1, 0, 0, 1, 0, 1, 1, 1], bool)
    assert unreliable_bands(f, flags) == [(1.0, 2.0), (5.0, 5.0), (7.0, 9.0)]
    assert unreliable_bands(f, np.zeros(10, bool)) == []


# ----------------------------------------------------------------- noise --


@pytest.mark.parametrize("rel", [0.01, 0.03])
def test_noise_estimate_recovers_the_relative_noise_level(rel):
    rng = np.random.default_rng(3)
    f = np.arange(200.0, 4001.0, 1.0)
    w = 2 * np.pi * f
    h = np.zeros(f.size, complex)
    for fr, zeta, a in ((700.0, 0.02, 1.0), (2100.0, 0.01, 0.5)):
        wr = 2 * np.pi * fr
        h += a / (wr**2 - w**2 + 2j * zeta * wr * w)
    z = rng.standard_normal((2, f.size))
    noisy = h + rel * np.abs(h) * (z[0] + 1j * z[1]) / math.sqrt(2)
    # 3800 lines: the median's relative standard error is about 2 %; 6 % is 3 sigma
    assert abs(estimate_relative_noise(noisy) / rel - 1) < 0.06


# ----------------------------------------------------------- modal model --


def random_modal_model(rng: np.random.Generator, n: int = 4) -> ModalModel:
    lc = np.tril(rng.standard_normal((n, n))) * 50.0
    return ModalModel(
        natural_frequency_hz=np.sort(rng.uniform(300, 3500, n)),
        shapes=rng.standard_normal((2, n)) * np.array([[1e-4], [1e-3]]) * 2 * np.pi * 1000,
        damping=lc @ lc.T,
        upper=np.array([[1e-9, -2e-9], [-2e-9, 5e-8]]),
        lower=np.array([[3e-3, 1e-3], [1e-3, -2e-2]]),
    )


def test_modal_model_is_reciprocal_and_passive_for_any_parameters():
    rng = np.random.default_rng(7)
    f = np.linspace(50, 6000, 2000)
    for _ in range(5):
        b = random_modal_model(rng).block(f)
        assert np.array_equal(b[:, 0, 1], b[:, 1, 0])  # l = n to the last bit
        assert is_reciprocal(b) and is_passive(b)
        # the damping-free part never produces power: -Im S is PSD, with a margin at the modes
        assert np.min(passivity_margin(b)) >= -1e-12


def test_passivity_check_detects_an_active_block():
    b = random_modal_model(np.random.default_rng(1)).block(F)
    assert not is_passive(np.conj(b))  # Im > 0: a source of energy
    asym = b.copy()
    asym[:, 0, 1] *= 1.01
    assert not is_reciprocal(asym)


# --------------------------------------------------------------- samples --


def make_samples(n_samples: int = 5) -> SpindleSamples:
    rng = np.random.default_rng(2)
    nominal = spindle_block(F)
    smp = nominal * (1 + 0.02 * rng.standard_normal((n_samples, 1, 1, 1)))
    return SpindleSamples(F, {"x": nominal}, {"x": smp}, {"note": "test"}, source="test")


def test_samples_file_round_trip_is_exact(tmp_path):
    s = make_samples()
    path = save_spindle_samples(tmp_path / "spindle_samples.npz", s)
    back = load_spindle_samples(path)
    assert back.directions == ["x"] and back.n_samples == 5 and back.metadata == {"note": "test"}
    assert np.array_equal(back.frequency_hz, s.frequency_hz)
    assert np.array_equal(back.samples["x"], s.samples["x"]) and np.array_equal(back.nominal["x"], s.nominal["x"])


def test_samples_file_errors(tmp_path):
    with pytest.raises(DataError, match="not found"):
        load_spindle_samples(tmp_path / "missing.npz")
    bad = tmp_path / "bad.npz"
    np.savez(bad, format=np.array("something/else"))
    with pytest.raises(DataError, match="format"):
        load_spindle_samples(bad)
    with pytest.raises(DataError, match="same, non-zero number"):
        SpindleSamples(F, {"x": spindle_block(F), "y": spindle_block(F)},
                       {"x": spindle_block(F)[None], "y": np.repeat(spindle_block(F)[None], 2, axis=0)})
    with pytest.raises(DataError, match="shape"):
        SpindleSamples(F, {"x": spindle_block(F)}, {"x": spindle_block(F)})


def tool_model(spindle: PointReceptance) -> ToolPointModel:
    holder = Holder(STEEL, (HolderSegment(0.020, 0.063), HolderSegment(0.0595, 0.050, 0.00794)))
    carbide = Material(580e9, 14500.0, 0.22, 0.001, name="carbide")
    tool = Tool(carbide, 0.1016, (ToolSegment(0.030, 0.00794, 0.8), ToolSegment(0.0716, 0.00794)))
    return ToolPointModel(holder, {"tool": tool}, {"x": spindle})


def test_mixing_uses_each_draws_own_spindle_sample():
    from bayes_rcsa.model import ConfigurationStack
    from bayes_rcsa.params import ForwardModel, GrowthLaw, LogUniform, ParameterModel

    s = make_samples(4)
    model = tool_model(s.receptance("x"))
    variants = [ToolPointModel(model.holder, model.tools, s.spindle(j)) for j in range(4)]
    assert np.array_equal(variants[2].spindle["x"].block, s.samples["x"][2])
    cfg = Configuration(0.03, "x")
    f = np.arange(600.0, 1400.0, 4.0)
    kx = np.array([1.8e6, 2.0e6, 2.2e6, 1.9e6, 2.1e6, 1.7e6])
    kt = np.full(6, 4.5e5)
    assignment = assign_samples(6, 4, np.random.default_rng(0))
    assert sorted(np.bincount(assignment, minlength=4)) == [1, 1, 2, 2]  # balanced
    pm = ParameterModel.from_priors(GrowthLaw(0.03, 0.03), {"k_xf": LogUniform(1e5, 1e9), "k_thetaM": LogUniform(1e3, 1e8)},
                                    {"c_xf": 10.0, "c_thetaM": 5e-4, "g_xf": 0.0, "g_thetaM": 0.0})
    forward = ForwardModel(pm, ConfigurationStack([model.precompute(cfg, f)]), model, spindle_samples=s)
    mixed = forward.frf({"k_xf": kx, "k_thetaM": kt, **{n: np.full(6, v) for n, v in pm.fixed.items()}}, assignment)
    for i, j in enumerate(assignment):
        ref = variants[j].precompute(cfg, f).frf(kx[i], kt[i], 10.0, 5e-4)
        np.testing.assert_allclose(mixed[i], ref, rtol=1e-12)
    with pytest.raises(SetupError):
        forward.frf({"k_xf": kx, "k_thetaM": kt, **{n: np.full(6, v) for n, v in pm.fixed.items()}}, assignment[:5])
