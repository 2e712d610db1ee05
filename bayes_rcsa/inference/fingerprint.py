"""The fingerprint of an identify run and the check that a checkpoint belongs to it (``--resume``).

:func:`run_fingerprint` lists everything that changes the log posterior or
the chain; it is stored in the checkpoint when a run starts, and
:func:`resume_state` refuses to continue a checkpoint whose fingerprint
differs, naming what changed.
"""

from __future__ import annotations

import hashlib

import numpy as np

from ..errors import SetupError
from .checkpoint import Checkpoint
from .problem import Problem
from .sampler import SamplerSettings

__all__ = ["run_fingerprint", "resume_state"]


def _sha(*arrays) -> str:
    h = hashlib.sha256()
    for a in arrays:
        a = np.ascontiguousarray(a if a is not None else np.empty(0))
        h.update(str(a.dtype).encode() + str(a.shape).encode())
        h.update(a.tobytes())
    return h.hexdigest()


def run_fingerprint(problem: Problem, seed: int, settings: SamplerSettings, n_walkers: int) -> dict:
    """Everything that changes the log posterior or the chain, for refusing a resume of a different run.

    Keys (each compared separately, so a refusal names what changed):
    ``method``, ``seed``, ``n_walkers``, ``check_every``; ``geometry`` and
    ``materials`` of holder and tools; ``spindle`` (the flange receptance
    data of every direction); ``data`` (frequency, values and coherence of
    every measurement used); ``band`` (each measurement's band);
    ``likelihood`` (noise floor, coherence threshold, tempering option);
    ``parameter_model`` (:meth:`ParameterModel.to_dict`: priors, fixed
    values, growth law, model terms); ``forward_model`` (a hash of the cached
    forward-model coefficients on the band lines, which catches any other
    change of the model).  Only where they differ from the defaults (so that
    the fingerprints of runs without them, and their checkpoints, stay as
    they were): ``extra_terms`` (each extra likelihood term's name and class,
    :attr:`.problem.Problem.extra_terms`: a checkpoint without cutting tests
    never continues a run with them) and ``sampler`` (fixed-steps mode, stored
    steps and moves of :class:`.sampler.SamplerSettings`).
    """
    model = problem.model
    holder = model.holder
    tools = sorted(model.tools.items())
    geometry = repr([[(s.length, s.outer_diameter, s.inner_diameter) for s in holder.segments]]
                    + [[name, t.total_length, [(s.length, s.diameter, s.diameter_ratio) for s in t.segments]]
                       for name, t in tools])
    materials = repr([holder.material] + [t.material for _, t in tools])
    spindle = {d: _sha(r.frequency_hz, r.block) for d, r in sorted(model.spindle.items())}
    obs = problem.observations
    stack = problem.likelihood.stack
    lik = problem.likelihood
    out = {
        "method": problem.method,
        "seed": int(seed),
        "n_walkers": int(n_walkers),
        "check_every": int(settings.check_every),
        "geometry": hashlib.sha256(geometry.encode()).hexdigest(),
        "materials": hashlib.sha256(materials.encode()).hexdigest(),
        "spindle": spindle,
        "data": [_sha(o.frequency_hz, o.values, o.coherence) for o in obs],
        "lengths": [o.configuration.clamping_length for o in obs],
        "band": [[o.band.lo_hz, o.band.hi_hz] for o in obs],
        "likelihood": {"noise_floor": lik.noise.floor, "min_coherence": lik.noise.min_coherence,
                       "tempering": problem.options.tempering},
        "parameter_model": problem.parameters.to_dict(),
        "forward_model": stack.cache_digest(),
    }
    if problem.extra_terms:
        out["extra_terms"] = [_term_identity(t) for t in problem.extra_terms]
    mode = {"n_steps": settings.n_steps, "n_burn": settings.n_burn, "store_every": settings.store_every,
            "move": settings.move}
    if mode != {"n_steps": None, "n_burn": 0, "store_every": 1, "move": "differential"}:
        out["sampler"] = mode
    return out


def _term_identity(term) -> str:
    """A term's ``fingerprint()`` if it has one, else its name and class."""
    own = getattr(term, "fingerprint", None)
    if callable(own):
        return str(own())
    return f"{getattr(term, 'name', '?')}:{type(term).__module__}.{type(term).__qualname__}"


_FINGERPRINT_LABELS = {
    "method": "the method", "seed": "--seed", "n_walkers": "the number of walkers", "check_every": "check_every",
    "geometry": "the holder/tool geometry", "materials": "the materials", "spindle": "the spindle data",
    "data": "a measurement file's content", "lengths": "the clamping lengths", "band": "the likelihood band",
    "likelihood": "the [likelihood] options", "parameter_model": "the priors, fixed values or [model] terms",
    "forward_model": "the forward model", "extra_terms": "the extra likelihood terms (--cuts)",
    "sampler": "the sampler mode or moves",
}


def resume_state(ckpt: Checkpoint | None, checkpoint_path, fingerprint: dict):
    """The checkpoint to continue (its :class:`.checkpoint.CheckpointState`), after checking that it belongs to
    this run (:func:`run_fingerprint`).

    Parameters
    ----------
    ckpt : Checkpoint or None
    checkpoint_path : path, named in messages
    fingerprint : dict, :func:`run_fingerprint` of the run to continue

    Raises
    ------
    SetupError
        No checkpoint, or one of a different run (the message names what changed).

    Reads without writing anything (a refused resume leaves the directory as
    it was), then restores a damaged copy from the good one.
    """
    if ckpt is None or not ckpt.exists():
        raise SetupError(f"--resume: no checkpoint found at {checkpoint_path}")
    state = ckpt.read()
    stored = state.meta.get("fingerprint", {})
    if stored != fingerprint:
        changed = [k for k in dict.fromkeys([*fingerprint, *stored]) if stored.get(k) != fingerprint.get(k)]
        what = ", ".join(_FINGERPRINT_LABELS.get(k, k) for k in changed) or "its format"
        raise SetupError(f"--resume: the checkpoint {checkpoint_path} belongs to a different run: {what} changed since "
                         f"it was written (start a new run without --resume, or use another --out)")
    ckpt.repair(state)
    return state
