"""Which test cut next: candidate cuts ranked by the expected reduction of a target's uncertainty (issue #23).

The current state of knowledge is a set of weighted draws d = 1..D (posterior
draws of the contact, each with its cutting coefficients K_t, K_r; weights
from cuts already made, or equal), summarised by each draw's stability limit
a_lim,d(n) at the candidate speeds and on a P(stable) map grid.  A cut at
(n, a) has two outcomes; under draw d it is stable with probability

    p_d = 1 - Φ(ln(a / a_lim,d(n)) / w)          (w: boundary width; w = 0 gives the step a < a_lim,d)

(the probit likelihood of :mod:`bayes_rcsa.cuts`).  Because the outcome is
binary, the expectation over outcomes is *exact*: with P_s = Σ w_d p_d, the
expected uncertainty after the cut is

    E[U] = P_s U(w ∘ p / P_s) + (1 - P_s) U(w ∘ (1 - p) / (1 - P_s)),

the re-weighting the nested Monte Carlo estimator of
:mod:`bayes_rcsa.design.estimators` performs with simulated data, here with
the two possible data sets enumerated (no Monte Carlo error).  Targets:

``map``
    uncertain area of the P(stable) map: U = mean over the map grid of
    4 P (1 - P) (1 where P = 0.5, 0 where the map is certain; the smooth
    form of "the share of the map with P(stable) between 5 % and 95 %",
    which is reported too).
``depth@N``
    90 % width of the depth limit at speed N (rpm), by the weighted
    quantiles of :func:`bayes_rcsa.design.estimators.weighted_widths`.
``mrr@P``
    the largest material removal rate index n·a (rpm m) among map cells
    with P(stable) >= P: here the *gain* (the expected best safe n·a after
    the cut minus the current one) is maximised, the value of the cut's
    information for the operating point.

A cut that chatters costs a tool: candidates whose predicted P(chatter) =
1 - P_s exceeds the user's ``risk_budget`` are never proposed (they are
listed with ``allowed = False``).  Everything is vectorised over candidates,
draws and map cells (matrix products); the only Python loop is over the
components of the width target (one speed).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..design.estimators import weighted_widths
from ..errors import SetupError

__all__ = ["NextCutTarget", "parse_next_cut_target", "CandidateCut", "NextCutResult", "p_stable_matrix",
           "map_uncertainty", "best_safe_mrr", "rank_next_cuts", "candidate_grid"]

#: P(stable) band of the reported "uncertain share" of the map.
UNCERTAIN_BAND = (0.05, 0.95)


@dataclass(frozen=True)
class NextCutTarget:
    """What the next cut should teach.

    Attributes
    ----------
    kind : {"map", "depth", "mrr"}
    speed_rpm : float or None, the speed of a ``depth`` target
    level : float or None, the required P(stable) of an ``mrr`` target
    text : str, as given
    """

    kind: str
    speed_rpm: float | None = None
    level: float | None = None
    text: str = ""


def parse_next_cut_target(text: str) -> NextCutTarget:
    """``map``, ``depth@SPEED`` (rpm) or ``mrr@LEVEL`` (P(stable) in (0, 1))."""
    t = (text or "").strip().lower()
    if t == "map":
        return NextCutTarget("map", text=text)
    kind, _, arg = t.partition("@")
    try:
        value = float(arg)
    except ValueError:
        value = float("nan")
    if kind == "depth" and math.isfinite(value) and value > 0:
        return NextCutTarget("depth", speed_rpm=value, text=text)
    if kind == "mrr" and math.isfinite(value) and 0 < value < 1:
        return NextCutTarget("mrr", level=value, text=text)
    raise SetupError(f"--next-cut-target {text!r}: expected map, depth@SPEED (rpm > 0) or mrr@LEVEL (0 < P < 1)")


@dataclass(frozen=True)
class CandidateCut:
    """One candidate cut and what it is expected to leave.

    Attributes
    ----------
    speed_rpm, depth_m : float
    p_chatter : float, predicted probability that the cut chatters (costs a tool)
    expected : float, expected target value after the cut (uncertainty; for ``mrr`` the best safe n·a)
    gain : float, current minus expected uncertainty (``mrr``: expected minus current n·a); > 0 is useful
    allowed : bool, p_chatter within the risk budget
    """

    speed_rpm: float
    depth_m: float
    p_chatter: float
    expected: float
    gain: float
    allowed: bool

    def as_dict(self) -> dict:
        return {"speed_rpm": self.speed_rpm, "depth_m": self.depth_m, "p_chatter": self.p_chatter,
                "expected": self.expected, "gain": self.gain, "allowed": self.allowed}


@dataclass(frozen=True)
class NextCutResult:
    """Ranking of candidate cuts, best first (allowed ones before the ones over the risk budget).

    Attributes
    ----------
    target : NextCutTarget
    candidates : list of CandidateCut, ranked
    current : float, the target's current value (uncertainty, or best safe n·a for ``mrr``)
    uncertain_share : float, share of the map cells with P(stable) in (0.05, 0.95) now
    risk_budget : float
    boundary_width : float
    ess : float, effective sample size of the current weights
    warnings : list of str
    """

    target: NextCutTarget
    candidates: list
    current: float
    uncertain_share: float
    risk_budget: float
    boundary_width: float
    ess: float
    warnings: list = field(default_factory=list)

    @property
    def best(self) -> CandidateCut | None:
        """The proposed cut: the best allowed candidate with a positive gain, else None."""
        c = self.candidates[0] if self.candidates else None
        return c if c is not None and c.allowed and c.gain > 0 else None

    def as_dict(self) -> dict:
        best = self.best
        return {
            "target": {"kind": self.target.kind, "speed_rpm": self.target.speed_rpm, "level": self.target.level,
                       "text": self.target.text},
            "current": self.current, "uncertain_share": self.uncertain_share, "risk_budget": self.risk_budget,
            "boundary_width": self.boundary_width, "ess": self.ess,
            "best": None if best is None else best.as_dict(),
            "candidates": [c.as_dict() for c in self.candidates],
            "warnings": list(self.warnings),
        }


def candidate_grid(speed_range, depth_range, n_speeds: int = 25, n_depths: int = 15) -> tuple[np.ndarray, np.ndarray]:
    """All (speed, depth) pairs of an n_speeds x n_depths grid over the ranges: two (C,) arrays."""
    s = np.linspace(float(speed_range[0]), float(speed_range[1]), n_speeds)
    a = np.linspace(float(depth_range[0]), float(depth_range[1]), n_depths)
    ss, aa = np.meshgrid(s, a, indexing="ij")
    return ss.ravel(), aa.ravel()


def p_stable_matrix(depth_m, limits_m, width: float) -> np.ndarray:
    """P(stable | draw) of cuts: (D, C) from depths (C,) and the draws' limits at the cuts' speeds (D, C).

    ``width`` = 0 gives the step ``depth < limit``; an infinite limit is always stable.
    """
    a = np.asarray(depth_m, dtype=float)[None, :]
    lim = np.asarray(limits_m, dtype=float)
    if width == 0:
        return (a < lim).astype(float)
    from scipy.special import ndtr

    with np.errstate(divide="ignore"):
        return 1.0 - ndtr(np.log(a / lim) / width)


def _map_p(weights: np.ndarray, indicator: np.ndarray) -> np.ndarray:
    """P(stable) of every map cell under each weight vector: (M, D) @ (D, G) -> (M, G)."""
    return weights @ indicator


def map_uncertainty(p: np.ndarray) -> np.ndarray:
    """Uncertain-area index: mean over cells of 4 P (1 - P), (...,) from (..., G)."""
    return np.mean(4.0 * p * (1.0 - p), axis=-1)


def best_safe_mrr(p: np.ndarray, mrr: np.ndarray, level: float) -> np.ndarray:
    """Largest n·a (rpm m) among cells with P >= level, (...,) from P (..., G) and n·a (G,); 0 where none."""
    return np.max(np.where(p >= level, mrr, 0.0), axis=-1)


def rank_next_cuts(target: NextCutTarget, cand_speed_rpm, cand_depth_m, cand_limits_m, map_speed_rpm, map_depth_m,
                   map_limits_m, weights=None, boundary_width: float = 0.1, risk_budget: float = 1.0,
                   target_limits_m=None) -> NextCutResult:
    """Rank candidate cuts by the expected reduction of the target's uncertainty (module docstring).

    Parameters
    ----------
    target : NextCutTarget
    cand_speed_rpm, cand_depth_m : (C,) rpm, m, candidate cuts
    cand_limits_m : (D, C) m, every draw's limit at each candidate's speed (+inf: no chatter found)
    map_speed_rpm : (S,) rpm; map_depth_m : (A,) m, the P(stable) map grid
    map_limits_m : (D, S) m, every draw's limit at the map speeds
    weights : (D,) or None (equal), current weights of the draws (e.g. from cuts already made)
    boundary_width : float >= 0, w of the probit (0: sharp boundary)
    risk_budget : float in (0, 1], largest acceptable P(chatter) of a proposed cut
    target_limits_m : (D,) m or None, every draw's limit at the ``depth`` target's speed (required then)

    Returns
    -------
    NextCutResult
    """
    cs = np.asarray(cand_speed_rpm, dtype=float)
    ca = np.asarray(cand_depth_m, dtype=float)
    cl = np.atleast_2d(np.asarray(cand_limits_m, dtype=float))
    ml = np.atleast_2d(np.asarray(map_limits_m, dtype=float))
    ms = np.asarray(map_speed_rpm, dtype=float)
    md = np.asarray(map_depth_m, dtype=float)
    n_draws = cl.shape[0]
    if cs.shape != ca.shape or cs.ndim != 1 or cl.shape != (n_draws, cs.size):
        raise SetupError(f"candidates: speeds {cs.shape}, depths {ca.shape} and limits {cl.shape} do not match "
                         f"(expected (C,), (C,) and (n_draws, C))")
    if ml.shape != (n_draws, ms.size):
        raise SetupError(f"map limits {ml.shape}: expected (n_draws={n_draws}, n_speeds={ms.size})")
    if np.any(np.isnan(cl)) or np.any(np.isnan(ml)):
        raise SetupError("depth limits contain NaN")
    if not (0 < risk_budget <= 1):
        raise SetupError(f"--risk-budget {risk_budget!r}: expected a probability in (0, 1]")
    if not (math.isfinite(boundary_width) and boundary_width >= 0):
        raise SetupError(f"boundary width {boundary_width!r}: expected a number >= 0")
    w = np.full(n_draws, 1.0 / n_draws) if weights is None else np.asarray(weights, dtype=float)
    if w.shape != (n_draws,) or np.any(w < 0) or not np.isfinite(w).all() or w.sum() <= 0:
        raise SetupError(f"weights {w.shape}: expected {n_draws} finite non-negative weights with a positive sum")
    w = w / w.sum()
    warnings: list[str] = []

    p = p_stable_matrix(ca, cl, boundary_width)  # (D, C)
    ps = w @ p  # (C,) P(stable) of each candidate
    with np.errstate(invalid="ignore", divide="ignore"):
        ws = (w[:, None] * p).T / ps[:, None]  # (C, D) weights after a stable outcome
        wc = (w[:, None] * (1.0 - p)).T / (1.0 - ps)[:, None]  # ... after chatter
    ws = np.where(ps[:, None] > 0, ws, 0.0)
    wc = np.where((1.0 - ps)[:, None] > 0, wc, 0.0)

    indicator = (md[None, None, :] < ml[:, :, None]).reshape(n_draws, -1).astype(float)  # (D, S*A)
    p_now = w @ indicator
    share = float(np.mean((p_now > UNCERTAIN_BAND[0]) & (p_now < UNCERTAIN_BAND[1])))
    if target.kind == "map":
        current = float(map_uncertainty(p_now))
        expected = ps * map_uncertainty(_map_p(ws, indicator)) + (1 - ps) * map_uncertainty(_map_p(wc, indicator))
        gain = current - expected
    elif target.kind == "mrr":
        mrr = (ms[:, None] * md[None, :]).ravel()
        current = float(best_safe_mrr(p_now, mrr, target.level))
        expected = (ps * best_safe_mrr(_map_p(ws, indicator), mrr, target.level)
                    + (1 - ps) * best_safe_mrr(_map_p(wc, indicator), mrr, target.level))
        gain = expected - current
        if current == 0:
            warnings.append(f"warning: no cell of the map reaches P(stable) >= {target.level:g} yet")
    elif target.kind == "depth":
        if target_limits_m is None:
            raise SetupError("a depth target needs every draw's limit at its speed (target_limits_m)")
        t = np.asarray(target_limits_m, dtype=float).reshape(-1, 1)
        if t.shape[0] != n_draws:
            raise SetupError(f"target limits {t.shape}: expected ({n_draws},)")
        if not np.all(np.isfinite(t)):
            top = float(md[-1])
            warnings.append(f"warning: {int(np.sum(~np.isfinite(t)))} draw(s) find no chatter at "
                            f"{target.speed_rpm:g} rpm; their limit is counted as the map's top depth {top:.4g} m "
                            f"(the width is a lower bound)")
            t = np.where(np.isfinite(t), t, top)
        current = float(weighted_widths(t, w[None])[0])
        expected = ps * weighted_widths(t, ws) + (1 - ps) * weighted_widths(t, wc)
        gain = current - expected
    else:
        raise SetupError(f"target kind {target.kind!r}: expected map, depth or mrr")

    allowed = (1.0 - ps) <= risk_budget + 1e-12
    if not np.any(allowed):
        warnings.append(f"warning: every candidate cut risks chatter with P > {risk_budget:g} (the risk budget); "
                        "none is proposed: give shallower depths or a larger --risk-budget")
    order = np.lexsort((-gain, ~allowed))  # allowed first, then by gain (largest first)
    cands = [CandidateCut(float(cs[i]), float(ca[i]), float(1.0 - ps[i]), float(expected[i]), float(gain[i]),
                          bool(allowed[i])) for i in order]
    if cands and cands[0].allowed and cands[0].gain <= 0:
        warnings.append("warning: no allowed candidate is expected to reduce the uncertainty; no cut is proposed")
    edge = _edge_warning(cands[0] if cands else None, cs, ca)
    if edge:
        warnings.append(edge)
    return NextCutResult(target, cands, current, share, float(risk_budget), float(boundary_width),
                         float(1.0 / np.sum(w**2)), warnings)


def _edge_warning(best: CandidateCut | None, cs: np.ndarray, ca: np.ndarray) -> str:
    """A proposed cut on the edge of the candidate grid: the optimum may lie outside it."""
    if best is None or not best.allowed or best.gain <= 0 or cs.size < 2:
        return ""
    sides = [name for name, v, lo, hi in (("speed", best.speed_rpm, cs.min(), cs.max()),
                                          ("depth", best.depth_m, ca.min(), ca.max()))
             if hi > lo and (v <= lo or v >= hi)]
    return (f"warning: the proposed cut lies on the edge of the candidate {' and '.join(sides)} range; a better cut "
            "may lie outside it") if sides else ""
