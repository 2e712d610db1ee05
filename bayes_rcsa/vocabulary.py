"""The printed names of everything a person reads: parameters, model effects, methods, criteria.

JSON, netCDF and CSV keep the stable identifiers (``k_xf``, ``spindle_error``, ``zoa``); every human output
(stderr, Markdown, HTML) shows the words here instead.  One table per kind, so that a new term, method or
criterion gets its printed name in one place (tests/test_human_outputs.py checks that every registered one has
one, and that no identifier reaches a human output).

Layer 0: the tables are plain strings; callers pass what they know (a parameter's ``label``, the measurement a
noise scale belongs to).
"""

from __future__ import annotations

import re

__all__ = ["CONTACT_PARAMETERS", "EFFECTS", "STABILITY_METHODS", "IDENTIFICATION_METHODS", "GAP_CRITERIA",
           "DEPTH_LIMITS", "in_words", "parameter_name", "parameter_symbol", "noise_name", "effect_name",
           "effect_sentence",
           "method_name", "identification_name", "gap_name", "depth_limit_name", "humanise", "identifiers"]

#: Contact and growth parameters: identifier -> (printed name, symbol).  The symbol is what a paper writes
#: (θ for theta), never the identifier itself.
CONTACT_PARAMETERS = {
    "k_xf": ("contact stiffness, translational", "kxf"),
    "k_thetaM": ("contact stiffness, rotational", "kθM"),
    "c_xf": ("contact damping, translational", "cxf"),
    "c_thetaM": ("contact damping, rotational", "cθM"),
    "g_xf": ("stiffness growth with clamping length, translational", "gxf"),
    "g_thetaM": ("stiffness growth with clamping length, rotational", "gθM"),
}

#: Model terms (effects of the model check): identifier -> (printed name, a sentence saying what it is).
EFFECTS = {
    "tip_mass": ("mass at the tool tip",
                 "A small mass at the tool tip, such as an accelerometer, that the model does not include."),
    "extra_mode": ("extra resonance on the spindle side",
                   "A resonance on the spindle or holder side (drawbar, holder flange, housing) that the spindle "
                   "file does not contain."),
    "spindle_error": ("spindle file off the real spindle",
                      "The spindle file comes from a spindle with stiffer or softer bearings than the real one "
                      "(another day, preload, temperature, identification error)."),
    "fluted_section": ("fluted part not as declared",
                       "The fluted part of the tool has another cross-section area and bending stiffness than its "
                       "declared diameter gives, or the tool was declared as one cylinder and its flutes are "
                       "missing from the setup."),
    "contact_damping": ("joint damping off the assumed value",
                        "The tool-holder joint damps more or less than assumed."),
    "joint_loss_factor": ("friction loss in the tool-holder joint",
                          "The tool-holder joint dissipates energy independently of frequency (micro-slip)."),
    "law_shape_uncertainty": ("shape of the stiffness-length law",
                              "The contact stiffness between the measured clamping lengths follows another law "
                              "than the straight line through its ends."),
    "nonlinear_stiffness_law": ("non-linear stiffness growth with clamping length",
                                "The contact stiffness does not grow linearly with clamping length: it gains most "
                                "of its stiffness early (saturating) or late (progressive)."),
    "spindle_rotation_omitted": ("spindle rotation missing from the spindle file",
                                 "The spindle file lacks its rotational receptances (only translation was "
                                 "measured), so the flange is softer in rotation than the file says."),
    "statistical_discrepancy": ("unexplained model error (statistical discrepancy)",
                                "A smooth gain and phase error of the whole model that no physical effect "
                                "explains; it widens the intervals."),
    "stiffness_step": ("step in contact stiffness along the shank",
                       "The contact stiffness rises in a step at some clamping length, where the shank reaches a "
                       "further contact zone of the holder (past a collet slot or relief groove)."),
    "baseline": ("the model without added effects", "The RCSA model as set up, with no added effect."),
}

#: Stability methods: identifier -> printed name.
STABILITY_METHODS = {"zoa": "zero-order approximation", "sdm": "semi-discretisation"}

#: Identification methods (``summary.json`` ``method``): identifier -> printed name.
IDENTIFICATION_METHODS = {
    "multi": "Bayesian fit over the clamping lengths",
    "single": "Bayesian fit at one clamping length",
    "deterministic": "least-squares fit",
    "library-predictive": "library prediction without a tap test",
}

#: Model-check criteria: identifier -> printed name.
GAP_CRITERIA = {
    "systematic_relative_residual": "systematic mismatch between model and measurement (relative, noise removed)",
}

#: What may set a recommended depth: identifier -> printed name.
DEPTH_LIMITS = {"stability": "stability", "max_depth": "the largest allowed depth",
                "flute_length": "the flute length", "speed_range": "the end of the analysed speed range"}

_NOISE = re.compile(r"^sigma_(\d+)$")


def parameter_symbol(name: str) -> str:
    """The symbol of a contact or growth parameter (``k_thetaM`` -> ``kθM``); ``""`` for the others."""
    return CONTACT_PARAMETERS.get(name, ("", ""))[1]


def noise_name(j: int, measurement: str | None = None) -> str:
    """The printed name of the relative noise scale of measurement ``j``: ``noise scale, 25 mm x``.

    ``measurement`` is the measurement's own description (clamping length and direction); without it the
    measurement is numbered from 1.
    """
    return f"noise scale, {measurement}" if measurement else f"noise scale of measurement {int(j) + 1}"


def parameter_name(name: str, label: str = "", measurements=None, symbol: bool = True) -> str:
    """A parameter's printed name.

    Parameters
    ----------
    name : str, the identifier (``k_xf``, ``sigma_2``, ``tip_mass_kg``)
    label : str, the parameter's own label (:attr:`bayes_rcsa.params.Parameter.label`), used for term parameters
    measurements : sequence of str, optional
        Description of each measurement in order (``"25 mm x"``); names the noise scales.
    symbol : bool, append the symbol of a contact parameter (``contact stiffness, translational (kxf)``)
    """
    if name in CONTACT_PARAMETERS:
        printed, sym = CONTACT_PARAMETERS[name]
        return f"{printed} ({sym})" if symbol else printed
    m = _NOISE.match(name)
    if m:
        j = int(m.group(1))
        where = measurements[j] if measurements is not None and j < len(measurements) else None
        return noise_name(j, where)
    if label and label != name and "_" not in label.split("[")[0].split("(")[0]:
        return label
    return humanise(name)


def effect_name(term: str) -> str:
    """A model effect's printed name (``spindle_error`` -> ``spindle file off the real spindle``)."""
    return EFFECTS[term][0] if term in EFFECTS else humanise(term)


def effect_sentence(term: str) -> str:
    """One sentence saying what the effect is."""
    return EFFECTS[term][1] if term in EFFECTS else humanise(term).capitalize() + "."


def method_name(method: str) -> str:
    """A stability method's printed name (``zoa`` -> ``zero-order approximation``)."""
    return STABILITY_METHODS.get(str(method).lower(), humanise(str(method)))


def identification_name(method: str, library: bool = False) -> str:
    """An identification method's printed name; ``library``: the fit used a library prior."""
    if library and method != "library-predictive":
        return "Bayesian fit of the tap tests with the library prior"
    return IDENTIFICATION_METHODS.get(method, humanise(str(method)))


def gap_name(criterion: str) -> str:
    """A model-check criterion's printed name; the key before a ``:`` when given the whole definition."""
    key = str(criterion).split(":")[0].strip()
    return GAP_CRITERIA.get(key, humanise(key))


def depth_limit_name(binding: str) -> str:
    """What set a recommended depth (``max_depth+speed_range`` -> ``the largest allowed depth and ...``)."""
    return " and ".join(DEPTH_LIMITS.get(p, humanise(p)) for p in str(binding).split("+"))


_IN_TEXT = None


def in_words(text: str, measurements=None, keys: bool = True) -> str:
    """``text`` (a warning, a verdict written for JSON) with the parameter, effect and criterion identifiers it
    quotes replaced by their printed names (``k_xf: R-hat = 1.02`` -> ``contact stiffness, translational (kxf):
    R-hat = 1.02``).  File names, paths and setup keys (quoted, after ``[table]`` or before ``=``) are left
    alone: those are what the user types (``keys=False``: a name before ``=`` is replaced too, for sentences such
    as ``c_xf = 10 N s/m (fixed in the fit)``)."""
    global _IN_TEXT
    if _IN_TEXT is None:
        words = sorted({*CONTACT_PARAMETERS, *EFFECTS, *GAP_CRITERIA} - {"baseline"}, key=len, reverse=True)
        # a quoted name, a name after a table heading or before "=" is a setup key the user types: kept
        core = r"(?<![\w./'\"`-])(?<!\] )(" + "|".join(map(re.escape, words)) + r"|sigma_\d+)(?![\w/'\"`-]|\.\w"
        _IN_TEXT = (re.compile(core + r"|\s*=(?!=))"), re.compile(core + ")"))

    def repl(m):
        name = m.group(1)
        if name in EFFECTS:
            return effect_name(name)
        if name in GAP_CRITERIA:
            return gap_name(name)
        return parameter_name(name, measurements=measurements)

    return _IN_TEXT[0 if keys else 1].sub(repl, str(text))


def humanise(identifier: str) -> str:
    """An identifier without its underscores (the fallback of every table here)."""
    return str(identifier).replace("_", " ").strip()


def identifiers() -> tuple[str, ...]:
    """Every identifier the tables here translate (the words no human output may show)."""
    return tuple(sorted({*CONTACT_PARAMETERS, *(e for e in EFFECTS if e != "baseline"), *STABILITY_METHODS,
                         *GAP_CRITERIA}))
