"""What one clamping length determines, and what two do: single- vs multi-length fits side by side.

The Python equivalent of ``bayes-rcsa identifiability`` on the bundled
example campaign: the contact is fitted from 25 mm alone, from 40 mm alone
(the literature method, one constant contact) and from both together (Method
II, growth law), with identical priors.  Printed per fit:

* the verdict of each stiffness -- "identified", "identified only in
  combination with k_thetaM" (the posterior is a ridge: the marginal width is
  several times the width at a fixed partner stiffness), "weakly identified"
  or "not identified" -- with its contraction and marginal / conditional
  width ratio;
* one sentence on what the data fix about the two stiffnesses together;
* the error of the median predicted natural frequency at the clamping
  lengths the fit did not use (the transfer error).

It writes identifiability.json/.md/.html, ``corner_overlay.png`` (the three
posteriors of the stiffness at each length on common axes) and
``forest.png`` to ``--out`` (default ``identifiability_single_vs_multi/``).

Run::

    python examples/identifiability_single_vs_multi.py [--out DIR]   # converged fits, a few minutes
    python examples/identifiability_single_vs_multi.py --quick       # short chains (not converged)

(``BAYES_RCSA_QUICK=1`` also selects the reduced run.)
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

from bayes_rcsa.data import example_setup
from bayes_rcsa.inference import SamplerSettings
from bayes_rcsa.io import load_setup
from bayes_rcsa.posterior import run_study, write_study
from bayes_rcsa.posterior.identifiability import fmt_contraction


def quick_requested(argv=None) -> bool:
    """``--quick`` on the command line or ``BAYES_RCSA_QUICK=1`` in the environment."""
    argv = sys.argv[1:] if argv is None else argv
    return "--quick" in argv or os.environ.get("BAYES_RCSA_QUICK", "") not in ("", "0")


def main(quick: bool | None = None, out: Path | None = None, seed: int = 0) -> dict:
    """Run the three fits and write the study; returns identifiability.json's content."""
    quick = quick_requested() if quick is None else quick
    argv = sys.argv[1:]
    out = Path(out or (argv[argv.index("--out") + 1] if "--out" in argv[:-1] else "identifiability_single_vs_multi"))
    setup = load_setup(example_setup())
    settings = SamplerSettings(max_steps=80, check_every=80, progress=False) if quick else SamplerSettings(progress=False)
    study = run_study(setup, [0.025, 0.040], settings, seed=seed)
    write_study(study, out, posteriors=False, seed=seed)
    doc = study.document
    print(f"{'fit':12s} {'stiffness':9s} {'verdict':46s} {'contraction':38s} {'marginal/conditional':>20s}")
    for f in doc["fits"]:
        for name in ("k_xf", "k_thetaM"):
            p = f["parameters"][name]
            print(f"{f['name']:12s} {name:9s} {p['verdict']:46s} {fmt_contraction(p['contraction']):38s} "
                  f"{p['width_ratio']:20.2f}")
    print()
    for f in doc["fits"]:
        print(f"{f['name']}: {f['stiffness_ridge']['statement']}")
        if f["transfer_error_pct"]:
            errs = ", ".join(f"{float(k) * 1e3:g} mm: {v:.2f} %" for k, v in f["transfer_error_pct"].items())
            print(f"    transfer error of the median natural frequency at the lengths not fitted: {errs}")
    print(f"\nwrote {out / 'identifiability.html'}, {out / 'corner_overlay.png'} and {out / 'forest.png'}")
    return doc


if __name__ == "__main__":
    main()
