"""Run a tool library's setups on any :class:`concurrent.futures.Executor`, resumably, one setup per task.

The unit of work is a whole setup (identify, then predict and lobes on its
posterior): setups are independent, so they are embarrassingly parallel and
a setup's steps need no data from any other task.  Each task runs in a worker
process of the executor -- local processes
(:class:`~concurrent.futures.ProcessPoolExecutor`, the default) or a Dask
cluster (``distributed.Client(address).get_executor()``) -- and writes only
under ``OUT/setups/<name>/``; the scheduling is the executor's.

Resuming: a setup whose ``result.json`` says ``done`` with the same
fingerprint (commands and setup file) is not recomputed; any other setup
directory is a half-done run and is cleared and run again.

A worker process that dies (killed, out of memory) breaks a local process
pool for every task in it.  The tasks that had not started are resubmitted to
a new pool; each task that was running is retried once alone, so an innocent
neighbour is recomputed and the culprit is reported ``lost`` (and rerun by
the next batch run) without taking anyone else with it.  Dask reschedules the
tasks of a lost worker itself and reports a task that keeps killing workers as
failed; that setup alone is then ``lost``.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import dataclasses
import json
import multiprocessing
import os
import shutil
import signal
import time
from pathlib import Path
from typing import Callable, Sequence

from ..errors import OutputError
from ..io.atomic import atomic_write_text, is_io_error, output_error
from .manifest import SetupJob
from .streams import output_to
from ..threads import THREAD_VARIABLES, limit_threads

__all__ = ["run_setup", "run_batch", "BatchResult", "limit_threads", "KILL_HOOK_ENV", "THREAD_VARIABLES",
           "WORKER_START"]

#: Fault injection for the tests: ``NAME:STEP`` makes the worker running setup NAME kill itself (SIGKILL)
#: just before STEP, as the kernel's out-of-memory killer would.
KILL_HOOK_ENV = "BAYES_RCSA_BATCH_KILL"

_RESULT = "result.json"
_STARTED = ".started"


def _read_json(path: Path):
    try:
        return json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None


def _quantiles(entry: dict, prefix: str, keys=("q05", "q50", "q95"), suffix: str = "") -> dict:
    return {f"{prefix}_{k}{suffix}": entry.get(f"{k}{suffix}") for k in keys}


def collect_row(job: SetupJob, setup_dir: Path) -> dict:
    """The summary-table row of a setup from its output files (what exists of them).

    Returns
    -------
    dict
        ``converged``, ``rhat_max``, ``ess_bulk_min``, ``n_steps``, every
        contact parameter's q05/q50/q95 (SI units), the dominant natural
        frequency's q05/q50/q95 (Hz) per predicted clamping length and
        direction, the recommended operating point of ``lobes``, and
        ``warnings`` (every step's warnings as ``"STEP: text"``, from its
        summary.json, frequencies.json, lobes.json) with their count
        ``n_warnings``.
    """
    row: dict = {}
    s = _read_json(setup_dir / "identify" / "summary.json")
    if s is not None:
        params = s.get("parameters", {}) or {}
        rhat = [p.get("rhat") for p in params.values() if p.get("rhat") is not None]
        ess = [p.get("ess_bulk") for p in params.values() if p.get("ess_bulk") is not None]
        row.update({"method": s.get("method"), "converged": s.get("converged"), "n_steps": s.get("n_steps"),
                    "rhat_max": max(rhat) if rhat else None, "ess_bulk_min": min(ess) if ess else None,
                    "identify_warnings": list(s.get("warnings", []))})
        for name, p in params.items():
            if not name.startswith("sigma_"):  # the noise scales are nuisance parameters
                row.update(_quantiles(p, name))
    f = _read_json(setup_dir / "predict" / "frequencies.json")
    if f is not None:
        for e in f.get("predictions", []):
            if e.get("dominant"):
                label = f"fn_{1e3 * e['clamping_length']:g}mm_{e['direction']}"
                row.update(_quantiles(e, label, suffix="_hz"))
    lob = _read_json(setup_dir / "lobes" / "lobes.json")
    # every step's warnings (data checks included), each named by its step: the table's warnings column
    warns = []
    for step, doc in (("identify", s), ("predict", f), ("lobes", lob)):
        if isinstance(doc, dict) and isinstance(doc.get("warnings"), list):
            warns += [f"{step}: {w}" for w in doc["warnings"]]
    row.update({"n_warnings": len(warns), "warnings": warns})
    if lob is not None:
        rec = lob.get("recommended") or {}
        row.update({"lobes_speed_rpm": rec.get("spindle_speed_rpm"), "lobes_depth_m": rec.get("depth_m"),
                    "lobes_p_stable": rec.get("p_stable_neighbourhood"), "lobes_limit": rec.get("binding_limit")})
    return row


def _step_error(log: Path, start: int) -> str:
    """The error line(s) a failed step printed (after byte ``start`` of the setup's log)."""
    with open(log, "rb") as fh:
        fh.seek(start)
        text = fh.read().decode("utf-8", "replace")
    lines = [ln.strip() for ln in text.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ": error: " in ln]
    return (errors or lines or ["no message"])[-1]


def run_setup(job: SetupJob, setup_dir, run_command: Callable[[list[str]], int], kill_hook: str = "") -> dict:
    """Run one setup's commands into ``setup_dir`` (cleared first) and write its ``result.json``.

    Runs in a worker process.  Output of the commands goes to
    ``setup_dir/log.txt``, not to the worker's terminal.

    Parameters
    ----------
    job : SetupJob
    setup_dir : path-like, ``OUT/setups/<name>``
    run_command : callable
        ``run_command(argv) -> exit status``: :func:`bayes_rcsa.cli.main.main`,
        passed in by the command line (the same code path as typing the
        commands by hand).
    kill_hook : str
        Fault injection for the tests (:data:`KILL_HOOK_ENV` of the calling
        process): ``"NAME:STEP"`` SIGKILLs this worker before STEP of setup NAME.

    Raises
    ------
    OutputError
        The setup folder cannot be written (full disk, read-only or vanished folder): the half-made folder is
        removed, and :func:`run_batch` stops (every other setup would fail the same way).  A step that fails
        (exit status != 0, its own file-system failures included) is not an exception: the setup is
        ``failed``; its folder keeps ``log.txt``, ``result.json`` and the outputs of the steps before the
        failed one (the failed step removes its own), and the next batch run clears and reruns it.

    Returns
    -------
    dict
        The setup's summary row: ``name``, ``status`` (``"done"`` or
        ``"failed"``), ``failed_step``, ``error``, ``seconds`` and the numbers
        of :func:`collect_row`.
    """
    limit_threads()
    d = Path(setup_dir)
    try:
        return _run_setup(job, d, run_command, kill_hook)
    except BaseException as exc:
        # the batch's own bookkeeping failed (full disk, read-only folder) or was interrupted: no half-made
        # setups/NAME/ stays behind (a rerun would clear it anyway, but a listing would show it)
        shutil.rmtree(d, ignore_errors=True)
        if is_io_error(exc) and not isinstance(exc, OutputError):
            raise output_error(exc, d) from exc
        raise


def _run_setup(job: SetupJob, d: Path, run_command: Callable[[list[str]], int], kill_hook: str) -> dict:
    if d.exists():
        shutil.rmtree(d)  # a half-done run: nothing of it is trusted
    d.mkdir(parents=True)
    atomic_write_text(d / _STARTED, f"{os.getpid()}\n")
    log = d / "log.txt"
    t0 = time.monotonic()
    status, failed_step, error = "done", None, None
    with open(log, "w", encoding="utf-8") as fh, output_to(fh):
        for step in job.steps:
            if kill_hook == f"{job.name}:{step}":
                fh.flush()
                os.kill(os.getpid(), signal.SIGKILL)
            argv = job.argv(step, d)
            print("$ bayes-rcsa " + " ".join(argv), flush=True)
            start = fh.tell()
            try:
                rc = run_command(argv)
            except SystemExit as exc:  # an argparse usage error of a manifest value
                rc = exc.code if isinstance(exc.code, int) else 2
            fh.flush()
            if rc != 0:
                status, failed_step, error = "failed", step, _step_error(log, start)
                break
    row = {"name": job.name, "status": status, "failed_step": failed_step, "error": error,
           "seconds": round(time.monotonic() - t0, 3), "setup": str(job.setup_file), "seed": job.seed,
           **collect_row(job, d)}
    atomic_write_text(d / _RESULT, json.dumps({"fingerprint": job.fingerprint(), "row": row}, indent=1,
                                              default=str))
    (d / _STARTED).unlink()  # finished: the folder holds the setup's outputs, its log and result.json only
    return row


@dataclasses.dataclass
class BatchResult:
    """Rows of every setup (manifest order) and what happened in this run.

    Attributes
    ----------
    rows : list of dict, one per setup (see :func:`run_setup`); ``status`` is
        ``done``, ``failed`` or ``lost`` (its worker died), ``reused`` is True
        for a finished setup taken from an earlier run
    ran : list of str, setups computed in this run
    reused : list of str, finished setups skipped
    """

    rows: list[dict]
    ran: list[str]
    reused: list[str]

    def count(self, status: str) -> int:
        return sum(1 for r in self.rows if r["status"] == status)


def finished_row(job: SetupJob, setup_dir: Path) -> dict | None:
    """The stored row of a setup finished by an earlier run with the same fingerprint, else ``None``."""
    doc = _read_json(setup_dir / _RESULT)
    if not doc or doc.get("fingerprint") != job.fingerprint() or doc.get("row", {}).get("status") != "done":
        return None
    return doc["row"]


#: Module the fork server of the local pool imports first (thread caps, then the heavy imports once).
WORKER_START = "bayes_rcsa.batch.worker_start"


def _local_pool(workers: int) -> cf.Executor:
    # forkserver: workers are forked from a clean server process (not from this one, whose BLAS pools and
    # threads a forked child would inherit) that has capped the BLAS threads and imported the package once
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload([WORKER_START])
    return cf.ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=limit_threads)


def _lost_row(job: SetupJob, why: str) -> dict:
    return {"name": job.name, "status": "lost", "failed_step": None, "error": why, "seconds": None,
            "setup": str(job.setup_file), "seed": job.seed}


def run_batch(jobs: Sequence[SetupJob], out_dir, run_command: Callable[[list[str]], int],
              executor: cf.Executor | None = None, workers: int = 1, force: bool = False,
              progress: Callable[[int, int, dict], None] | None = None) -> BatchResult:
    """Run every unfinished setup of ``jobs``, one task per setup, and collect the rows.

    Parameters
    ----------
    jobs : sequence of SetupJob (:func:`bayes_rcsa.batch.load_manifest`)
    out_dir : path-like; setup ``name`` writes ``out_dir/setups/name/``
    run_command : ``run_command(argv) -> exit status`` (see :func:`run_setup`)
    executor : Executor or None
        Where the tasks run (e.g. ``distributed.Client(address).get_executor()``);
        ``None``: a local process pool of ``workers`` processes, created and
        shut down here.
    workers : int, processes of the local pool
    force : bool, recompute finished setups too
    progress : callable or None
        ``progress(n_finished, n_to_run, row)`` after each setup of this run.

    Returns
    -------
    BatchResult
    """
    out_dir = Path(out_dir).absolute()  # workers (on other machines, too) need no knowledge of our cwd
    root = out_dir / "setups"
    root.mkdir(parents=True, exist_ok=True)
    rows: dict[str, dict] = {}
    reused = []
    todo = []
    for job in jobs:
        row = None if force else finished_row(job, root / job.name)
        if row is not None:
            rows[job.name] = {**row, "reused": True}
            reused.append(job.name)
        else:
            todo.append(job)
            # a marker of an earlier killed run would make this one look as if it had started in this run
            with contextlib.suppress(FileNotFoundError):
                (root / job.name / _STARTED).unlink()
    n_total, n_done = len(todo), 0

    def finish(job, row):
        nonlocal n_done
        rows[job.name] = {**row, "reused": False}
        n_done += 1
        if progress is not None:
            progress(n_done, n_total, rows[job.name])

    # read here, not in the worker: local workers are forked from a server started with an earlier environment
    kill_hook = os.environ.get(KILL_HOOK_ENV, "")

    def submit(ex, job):
        return ex.submit(run_setup, job, str(root / job.name), run_command, kill_hook)

    def submit_all(ex, batch):
        return {submit(ex, job): job for job in batch}

    queue = list(todo)
    while queue:
        own = executor is None
        ex = _local_pool(min(workers, len(queue))) if own else executor
        broken = []
        try:
            futures = submit_all(ex, queue)
            for fut in cf.as_completed(futures):
                job = futures[fut]
                try:
                    finish(job, fut.result())
                except cf.BrokenExecutor:
                    broken.append(job)
                except OutputError:
                    # the output folder cannot be written (full disk, read-only): every other setup would fail
                    # the same way; the command reports it on one line and removes what this run made
                    raise
                except Exception as exc:  # the executor's report of a lost task (e.g. Dask's KilledWorker)
                    finish(job, _lost_row(job, f"worker lost: {type(exc).__name__}: {exc}"))
        finally:
            if own:
                ex.shutdown(wait=True, cancel_futures=True)
        # Tasks that never started go back to a new pool; each task that was running is retried alone.
        queue = [j for j in broken if not (root / j.name / _STARTED).exists()]
        for job in (j for j in broken if (root / j.name / _STARTED).exists()):
            if not own:
                finish(job, _lost_row(job, "worker process died"))
                continue
            with _local_pool(1) as solo:
                try:
                    finish(job, submit(solo, job).result())
                except cf.BrokenExecutor:
                    finish(job, _lost_row(job, "worker process died (killed or out of memory); rerun the batch "
                                               "to retry this setup"))
    ordered = [rows[j.name] for j in jobs]
    return BatchResult(ordered, [j.name for j in todo], reused)
