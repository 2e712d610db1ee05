"""No crash: ``bayes-rcsa discrepancy`` on campaigns of both benches, every effect, two magnitudes, several seeds.

Each campaign runs through the real command line (in process, plots included, ``--json``); a run must end
with exit status 0 and a complete output directory, or with exit status 2 and one line on stderr.  Any other
outcome (a traceback, another exit status, a missing file, a point estimate outside its own interval in
discrepancy.json) is counted as a crash and printed.  Every campaign here is valid bench data, so an exit
status 2 (a clean refusal) is also counted, as "refused", with its line: the sweeps up to issue #19's last
round counted the rotor bench's contact damping at 50x as fine while it was refused in every run.

Run: ``OMP_NUM_THREADS=1 python benchmarks/discrepancy_sweep.py --seeds 2`` (prints a Markdown table;
``--seed-start`` and ``--only`` select seeds and cases).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from bayes_rcsa.cli.main import main as cli


def fe_cases():
    from bayes_rcsa.synthetic import HIDDEN_EFFECTS

    for name, info in HIDDEN_EFFECTS.items():
        for scale in (0.5, 2.0):
            # half and twice the default, within the effect's own range (the fluted reduction beyond 30 % and
            # a dropped fraction beyond 1 are not physical)
            mag = min(info.default * scale, 0.3 if name == "fluted_section" else info.max_magnitude)
            yield f"fe {name}={mag:g}", "fe", {name: mag}, {}


def rotor_cases():
    from bayes_rcsa.synthetic.rotor import ROTOR_EFFECTS

    for name, info in ROTOR_EFFECTS.items():
        for mag in (info.low, info.high):
            yield f"rotor {name}={mag:g}", "rotor", {name: mag}, {}
    yield "rotor fluted solid", "rotor", {"fluted_section": True}, {"fluted_declared": "solid"}
    for kind in ("one_bearing", "rear"):
        yield f"rotor spindle_error {kind}", "rotor", {"spindle_error": True}, {"spindle_error_kind": kind}
    yield "rotor tip_mass+spindle_error", "rotor", {"tip_mass": True, "spindle_error": True}, {}
    yield "rotor clean", "rotor", {}, {}


def write(gen: str, effects: dict, overrides: dict, seed: int, root: Path) -> Path:
    if gen == "fe":
        from bayes_rcsa.synthetic import default_bench_config, generate_campaign, write_campaign

        cfg = default_bench_config(hidden_effects=effects)
        return write_campaign(generate_campaign(cfg, np.random.default_rng(seed)), root / "c", overwrite=True)
    from bayes_rcsa.synthetic import rotor

    cfg = rotor.rotor_bench_config(hidden_effects=effects, **overrides)
    return rotor.write_rotor_campaign(rotor.generate_rotor_campaign(cfg, np.random.default_rng(seed)), root / "c",
                                      overwrite=True)


def check_outputs(out: Path) -> list[str]:
    problems = []
    for name in ("discrepancy.json", "summary.md", "frequency_errors.png"):
        if not (out / name).exists():
            problems.append(f"missing {name}")
    if (out / "discrepancy.json").exists():
        r = json.loads((out / "discrepancy.json").read_text())
        for m in r["measurements_after"]:
            for md in m["modes"]:
                q = md["model_interval"]
                if q["q05"] is not None and not (q["q05"] <= md["model_hz"] <= q["q95"]):
                    problems.append(f"{m['source']}: point {md['model_hz']:.1f} outside [{q['q05']:.1f}, {q['q95']:.1f}]")
    return problems


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--seed-start", type=int, default=2000, help="first seed (the table's seeds are 2000 and 2001; "
                    "other seeds hunt for crashes beyond them)")
    ap.add_argument("--only", default=None, help="run only cases whose label contains this text")
    a = ap.parse_args()
    rows, crashes, refused, n = [], 0, 0, 0
    for label, gen, effects, overrides in [*fe_cases(), *rotor_cases()]:
        if a.only and a.only not in label:
            continue
        for s in range(a.seeds):
            seed = a.seed_start + s
            with tempfile.TemporaryDirectory() as tmp:
                root = Path(tmp)
                setup = write(gen, effects, overrides, seed, root)
                out = root / "out"
                err, std = io.StringIO(), io.StringIO()
                t0 = time.perf_counter()
                try:
                    with contextlib.redirect_stderr(err), contextlib.redirect_stdout(std):
                        code = cli(["discrepancy", str(setup), "--lengths", "0.025,0.04", "--out", str(out),
                                    "--seed", str(seed), "--json"])
                except SystemExit as exc:
                    code = exc.code
                except Exception as exc:  # the sweep counts what escapes the command line as a crash
                    code = f"{type(exc).__name__}: {exc}"
                dt = time.perf_counter() - t0
                problems, outcome = [], "ok"
                if code == 0:
                    problems = check_outputs(out)
                elif code == 2:
                    lines = [x for x in err.getvalue().splitlines() if x.startswith("bayes-rcsa") and "error" in x]
                    if "Traceback" in err.getvalue() or len(lines) != 1:
                        problems.append("exit 2 without exactly one error line")
                    else:
                        refused += 1
                        outcome = f"refused: {lines[0]}"
                else:
                    problems.append(f"exit {code}")
                n += 1
                crashes += bool(problems)
                named = ""
                if code == 0:
                    named = json.loads(std.getvalue().strip().splitlines()[-1]).get("named_effect")
                rows.append(f"| {label} | {seed} | {code} | {named} | {'; '.join(problems) or outcome} | {dt:.0f} |")
                print(rows[-1], flush=True)
    print("\n| case | seed | exit | named | outcome | s |\n|---|---|---|---|---|---|")
    print("\n".join(rows))
    print(f"\n{n} runs, {crashes} crashes, {refused} valid campaigns refused (exit 2)")


if __name__ == "__main__":
    main()
