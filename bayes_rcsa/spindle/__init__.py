"""Spindle-holder interface identification from standard-artifact hammer tests (paper section 2.3).

The flange receptance ``S = [[h, l], [n, p]]`` of the spindle (per direction)
is identified once per machine from hammer tests on a standard artifact (a
shrink-fit holder with a bonded blank): H11 at the blank's free end, the
cross receptances H12/H21 to a second point, and H22 there.  Inverse
receptance coupling with the artifact's free-free Timoshenko model gives S
line by line; a reciprocal, passive modal model smooths it; bootstrap
samples carry its uncertainty into tool-point predictions.  See
docs/spindle.md.

Main entry points
-----------------
:func:`load_artifact` -> :class:`ArtifactSetup`
:func:`identify_direction` -> :class:`SpindleIdentification`
:func:`load_spindle_samples` -> :class:`SpindleSamples`, an input of the forward model
(``ForwardModel(..., spindle_samples=)``, ``predict`` and ``lobes``); :func:`assign_samples` gives
every posterior draw a sample.
"""

from .artifact import Artifact, ArtifactMeasurement, ArtifactSetup, load_artifact
from .identification import SpindleIdentification, identify_direction
from .inverse import forward_artifact, inverse_exact, inverse_from_free_end_block
from .smoothing import ModalModel, is_passive, is_reciprocal
from .substructure import ArtifactReceptances, artifact_receptances
from .uncertainty import (
    SAMPLES_FORMAT, SpindleSamples, assign_samples, load_spindle_samples, save_spindle_samples,
)

__all__ = [
    "Artifact", "ArtifactMeasurement", "ArtifactSetup", "load_artifact",
    "SpindleIdentification", "identify_direction",
    "forward_artifact", "inverse_exact", "inverse_from_free_end_block",
    "ModalModel", "is_passive", "is_reciprocal", "ArtifactReceptances", "artifact_receptances",
    "SAMPLES_FORMAT", "SpindleSamples", "load_spindle_samples", "save_spindle_samples", "assign_samples",
]
