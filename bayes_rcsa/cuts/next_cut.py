"""Which test cut next: candidate cuts ranked by the expected reduction of a target's uncertainty (issue #23).

The current state of knowledge is a set of weighted draws d = 1..D (posterior
draws of the contact, each with its cutting coefficients K_t, K_r; weights
from cuts already made, or equal), summarised by each draw's stability limit
a_lim,d(n) at the candidate speeds and on a P(stable) map grid.  A cut at
(n, a) has two outcomes; under draw d it is stable with probability

    p_d = 1 - ε - (1 - 2ε) Φ(ln(a / a_lim,d(n)) / w)     (w: boundary width, ε: label error)

(the probit likelihood of :mod:`bayes_rcsa.cuts.likelihood`, same defaults).  Because the outcome is
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
from ..errors import DataError, SetupError
from ..stats.weights import MIN_ESS, effective_sample_size, normalise_log_weights
from ..units import mm, rpm
from .likelihood import DEFAULT_BOUNDARY_WIDTH, DEFAULT_LABEL_ERROR, chatter_probability

__all__ = ["NextCutTarget", "parse_next_cut_target", "CandidateCut", "NextCutResult", "p_stable_matrix",
           "map_uncertainty", "best_safe_mrr", "rank_next_cuts", "candidate_grid", "run_next_cut", "next_cut_figure",
           "write_next_cut_outputs"]

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
    map_speed_rpm, map_depth_m, p_stable_map : the current P(stable) map (S,), (A,), (S, A)
    context : dict, JSON-able inputs (posterior, cuts so far, cutting conditions, prior)
    cuts_so_far : (speed (k,), depth (k,), stable (k,)) or None, for the plot
    """

    target: NextCutTarget
    candidates: list
    current: float
    uncertain_share: float
    risk_budget: float
    boundary_width: float
    ess: float
    warnings: list = field(default_factory=list)
    map_speed_rpm: np.ndarray | None = None
    map_depth_m: np.ndarray | None = None
    p_stable_map: np.ndarray | None = None
    context: dict = field(default_factory=dict)
    cuts_so_far: tuple | None = None

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
            "map": None if self.p_stable_map is None else {
                "speed_rpm": self.map_speed_rpm, "depth_m": self.map_depth_m, "p_stable": self.p_stable_map},
            **self.context,
            "warnings": list(self.warnings),
        }


def candidate_grid(speed_range, depth_range, n_speeds: int = 25, n_depths: int = 15) -> tuple[np.ndarray, np.ndarray]:
    """All (speed, depth) pairs of an n_speeds x n_depths grid over the ranges: two (C,) arrays."""
    s = np.linspace(float(speed_range[0]), float(speed_range[1]), n_speeds)
    a = np.linspace(float(depth_range[0]), float(depth_range[1]), n_depths)
    ss, aa = np.meshgrid(s, a, indexing="ij")
    return ss.ravel(), aa.ravel()


def p_stable_matrix(depth_m, limits_m, width: float, label_error: float = 0.0) -> np.ndarray:
    """P(stable | draw) of cuts: (D, C) from depths (C,) and the draws' limits at the cuts' speeds (D, C).

    ``width`` = 0 and ``label_error`` = 0 give the step ``depth < limit``; an infinite limit is stable
    (with probability 1 - ε).
    """
    a = np.asarray(depth_m, dtype=float)[None, :]
    return 1.0 - chatter_probability(a, np.asarray(limits_m, dtype=float), width, label_error)


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
                   map_limits_m, weights=None, boundary_width: float = DEFAULT_BOUNDARY_WIDTH,
                   risk_budget: float = 1.0, target_limits_m=None, label_error: float = 0.0) -> NextCutResult:
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
    label_error : float ε in [0, 0.5), chance that a cut far from the boundary is reported the other way
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

    p = p_stable_matrix(ca, cl, boundary_width, label_error)  # (D, C)
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
                            f"{rpm(target.speed_rpm)}; their limit is counted as the map's top depth {mm(top)} "
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
                         effective_sample_size(w, normalised=True), warnings)


def _edge_warning(best: CandidateCut | None, cs: np.ndarray, ca: np.ndarray) -> str:
    """A proposed cut on the edge of the candidate grid: the optimum may lie outside it."""
    if best is None or not best.allowed or best.gain <= 0 or cs.size < 2:
        return ""
    sides = [name for name, v, lo, hi in (("speed", best.speed_rpm, cs.min(), cs.max()),
                                          ("depth", best.depth_m, ca.min(), ca.max()))
             if hi > lo and (v <= lo or v >= hi)]
    return (f"warning: the proposed cut lies on the edge of the candidate {' and '.join(sides)} range; a better cut "
            "may lie outside it") if sides else ""


# ------------------------------------------------------------------ workflow --
def run_next_cut(setup_path, posterior_path, cutting, clamping_length: float, prior, cand_speeds_rpm,
                 cand_depths_m, target: NextCutTarget, risk_budget: float = 1.0, cuts_path=None,
                 n_draws: int | None = 500, particles: int = 4, seed: int = 0,
                 boundary_width: float = DEFAULT_BOUNDARY_WIDTH, label_error: float = DEFAULT_LABEL_ERROR,
                 tool: str | None = None, method: str = "zoa", map_points: int = 50) -> NextCutResult:
    """Rank the candidate cuts (every speed x every depth) at ``clamping_length`` for ``target``.

    The hammer posterior's draws (``n_draws`` of them, with the growth-law transfer where needed) are
    paired with ``particles`` draws each of the cutting coefficients from ``prior``
    (:class:`~bayes_rcsa.cuts.coefficients.CoefficientPrior`); cuts already made (``cuts_path``, the
    ``update`` file format) weight the particles by the cut likelihood.  The limits at the candidate and
    map speeds come from ``method`` on each draw's X/Y tool-point FRFs
    (:func:`~bayes_rcsa.cuts.likelihood.inverse_limits_at_cuts`).

    Parameters
    ----------
    setup_path, posterior_path : paths (setup TOML, posterior.nc of ``identify``)
    cutting : CuttingConditions of the candidate cuts (its K_t, K_r are replaced by the prior's)
    clamping_length : float, m
    prior : CoefficientPrior
    cand_speeds_rpm : (S,) rpm; cand_depths_m : (A,) m, the candidates are all S x A pairs
    target : NextCutTarget
    risk_budget : float in (0, 1]
    cuts_path : path or None, cuts made so far
    n_draws : int or None (all), hammer draws; particles : int, coefficient draws per hammer draw
    seed : int
    boundary_width, label_error : of the cut likelihood
    tool : str or None (the setup's only tool)
    method : stability method
    map_points : int, speeds and depths of the P(stable) map (over the candidate ranges)

    Returns
    -------
    NextCutResult (with the current map and JSON-able context)
    """
    from ..io import load_setup
    from ..stability.posterior_frf import flute_length
    from .data import check_supported, cut_groups, prepare_cuts
    from .frf import posterior_dynamics
    from .likelihood import CutGroup, CutLikelihood, inverse_limits_at_cuts

    rng = np.random.default_rng(seed)
    s_axis = np.unique(np.asarray(cand_speeds_rpm, dtype=float))
    a_axis = np.unique(np.asarray(cand_depths_m, dtype=float))
    if s_axis.size < 1 or a_axis.size < 1 or np.any(s_axis <= 0) or np.any(a_axis <= 0):
        raise SetupError("--speeds and --depths: expected positive speeds (rpm) and depths (m)")
    if int(particles) != particles or particles < 1:
        raise SetupError(f"particles={particles!r}: expected an integer >= 1")
    setup0 = load_setup(setup_path, load_data=False, load_spindle=False)
    if tool is None:
        if len(setup0.tools) != 1:
            raise SetupError(f"the setup has several tools {sorted(setup0.tools)}; give --tool NAME")
        tool = next(iter(setup0.tools))
    elif tool not in setup0.tools:
        raise SetupError(f"--tool {tool!r}: not a tool of the setup ({', '.join(sorted(setup0.tools))})")
    fl = flute_length(setup0.tools[tool])
    if fl is not None and a_axis[-1] > fl:
        raise DataError(f"--depths up to {a_axis[-1]:g} m: deeper than the flute length {fl:g} m of tool {tool!r}; "
                        "depths are in metres (was it in mm?)")
    key = (float(clamping_length), tool)
    cuts = None
    setups = [key]
    if cuts_path is not None:
        from ..stability.tests_io import read_cut_table

        cuts = prepare_cuts(read_cut_table(cuts_path), cutting, clamping_length, setup0.tools, tool,
                            lambda name: flute_length(setup0.tools[name]))
        setups = sorted(set(setups) | set(cuts.setups()))
    dyn = posterior_dynamics(setup_path, posterior_path, setups, n_draws, rng)
    f = dyn.frequency_hz
    top = 60.0 * float(np.max(f)) / cutting.flutes
    if s_axis[-1] > top:
        raise DataError(f"--speeds up to {s_axis[-1]:g} rpm: outside the speed range the FRF band supports (at most "
                        f"{top:.0f} rpm with {cutting.flutes} flutes: the tooth-passing frequency must lie in the band)")
    map_s = np.linspace(s_axis[0], s_axis[-1], map_points) if s_axis.size > 1 else s_axis
    map_a = np.linspace(a_axis[-1] / map_points, a_axis[-1], map_points)
    extra = [] if target.kind != "depth" else [float(target.speed_rpm)]
    speeds = np.unique(np.concatenate([s_axis, map_s, extra]))
    gx, gy = dyn.frfs[key]
    group = CutGroup(gx, gy, f, cutting, np.arange(speeds.size), speeds)
    inv = inverse_limits_at_cuts([group], speeds.size, prior, method)  # (nodes, D, S)
    n_d = inv.shape[1]
    draw = np.repeat(np.arange(n_d), int(particles))
    u, node = prior.sample(rng, draw.size)
    with np.errstate(divide="ignore"):
        limits = 1.0 / (inv[node, draw] * np.exp(u)[:, None])  # (P, S) m; inf where no limit
    warnings: list[str] = []
    weights = None
    so_far = None
    if cuts is not None:
        groups = cut_groups(cuts, dyn.frfs, f)
        inv_c = inverse_limits_at_cuts(groups, cuts.n_cuts, prior, method)
        check_supported(cuts, inv_c)
        logw = CutLikelihood(inv_c, cuts.depth_m, cuts.chatter, label_error)(draw, u, node, boundary_width)
        weights = normalise_log_weights(logw, refuse=False)  # no weight at all: refused by rank_next_cuts
        ess = effective_sample_size(np.bincount(draw, weights, n_d))
        if ess < MIN_ESS:
            warnings.append(f"warning: the {cuts.n_cuts} cut(s) so far leave {ess:.0f} effective hammer draws of {n_d}; "
                            "the ranking rests on few draws (use more --draws)")
        so_far = (cuts.speed_rpm, cuts.depth_m, ~cuts.chatter)
    col = {v: i for i, v in enumerate(speeds)}
    cs, ca = (x.ravel() for x in np.meshgrid(s_axis, a_axis, indexing="ij"))
    res = rank_next_cuts(target, cs, ca, limits[:, [col[v] for v in cs]], map_s, map_a,
                         limits[:, [col[v] for v in map_s]], weights, boundary_width, risk_budget,
                         limits[:, col[extra[0]]] if extra else None, label_error)
    w = np.full(draw.size, 1.0 / draw.size) if weights is None else weights
    p_map = np.einsum("p,psa->sa", w, (map_a[None, None, :] < limits[:, [col[v] for v in map_s], None]))
    for name, lo, hi in (("speed", s_axis[0], s_axis[-1]), ("depth", a_axis[0], a_axis[-1])):
        if lo == hi:
            warnings.append(f"warning: a single candidate {name}; the ranking is over the other axis only")
    context = {"inputs": {"setup": str(setup_path), "posterior": str(posterior_path),
                          "cuts": None if cuts_path is None else str(cuts_path),
                          "n_cuts_so_far": 0 if cuts is None else cuts.n_cuts, "clamping_length_m": float(clamping_length),
                          "tool": tool, "method": method, "n_draws": n_d, "particles_per_draw": int(particles),
                          "seed": seed, "label_error": label_error, "coefficient_prior": prior.describe(),
                          "cutting": {"flutes": cutting.flutes, "radial_immersion": cutting.radial_immersion,
                                      "milling": cutting.milling, "feed": cutting.feed}}}
    return NextCutResult(res.target, res.candidates, res.current, res.uncertain_share, res.risk_budget,
                         res.boundary_width, res.ess, warnings + res.warnings, map_s, map_a, p_map, context, so_far)


def write_next_cut_outputs(result: NextCutResult, out_dir, plots: bool = True) -> list:
    """Write ``design.json`` (and ``design.png``: the P(stable) map, the candidates' gains, the proposal)."""
    from pathlib import Path

    from ..io.atomic import atomic_write_text
    from ..io.jsonable import dumps_strict

    out = Path(out_dir)
    doc = {"mode": "next_cut", **result.as_dict()}
    written = []
    if plots:
        written.append(_plot(result, out / "design.png"))
        doc["plot"] = "design.png"
    atomic_write_text(out / "design.json", dumps_strict(doc, indent=2) + "\n")
    return [out / "design.json"] + written


def _plot(result: NextCutResult, path):
    from ..io.figures import save_png

    return save_png(next_cut_figure(result), path)


def next_cut_figure(result: NextCutResult):
    """The current P(stable) map, the candidates' expected gains and the proposed cut (a matplotlib Figure)."""
    from ..io.figures import finish, new_figure

    fig = new_figure(7.0, 4.4)
    ax = fig.add_subplot(111)
    s, a = result.map_speed_rpm, result.map_depth_m
    im = ax.pcolormesh(s, 1e3 * a, result.p_stable_map.T, cmap="RdYlGn", vmin=0, vmax=1, shading="nearest")
    fig.colorbar(im, ax=ax, label="P(stable) now")
    c = result.candidates
    ok = [x for x in c if x.allowed]
    bad = [x for x in c if not x.allowed]
    gmax = max((x.gain for x in c), default=0.0)
    if ok:
        ax.scatter([x.speed_rpm for x in ok], [1e3 * x.depth_m for x in ok],
                   s=[4 + 60 * max(x.gain, 0) / gmax if gmax > 0 else 4 for x in ok], c="k", alpha=0.5,
                   label="candidates (size: expected gain)")
    if bad:
        ax.scatter([x.speed_rpm for x in bad], [1e3 * x.depth_m for x in bad], s=6, marker="x", c="0.3", alpha=0.5,
                   label=f"P(chatter) > risk budget {result.risk_budget:g}")
    if result.cuts_so_far is not None:
        sp, dp, st = result.cuts_so_far
        ax.scatter(sp[st], 1e3 * dp[st], marker="o", facecolors="none", edgecolors="b", label="cuts so far: stable")
        ax.scatter(sp[~st], 1e3 * dp[~st], marker="^", c="m", label="cuts so far: chatter")
    b = result.best
    if b is not None:
        ax.scatter([b.speed_rpm], [1e3 * b.depth_m], marker="*", s=220, c="gold", edgecolors="k",
                   label=f"next cut: {b.speed_rpm:.0f} rpm, {1e3 * b.depth_m:.3g} mm (P(chatter) {b.p_chatter:.2f})")
    ax.set_xlabel("spindle speed (rpm)")
    ax.set_ylabel("axial depth (mm)")
    ax.set_title(f"next cut for target {result.target.text or result.target.kind}", fontsize=9)
    ax.legend(fontsize=8, loc="upper right")
    finish(fig)
    return fig
