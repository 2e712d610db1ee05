"""The physical model: materials and sections, Timoshenko beams, coupling, assembly.

The physics without parameters: materials and sections, exact Timoshenko
segments (:mod:`.timoshenko`), 2x2 receptance coupling (:mod:`.coupling`,
including ``add_end_impedance`` for attachments), geometry, measured
receptances, and :mod:`.assembly`: ``ToolPointModel.precompute`` caches per
configuration everything independent of the contact (the flange receptance,
the holder and tool two-ports, the spindle+holder coupling and the seven
fast-path coefficients of ``tool_point_coefficients``, the single
implementation of that formula); ``ConfigurationStack`` evaluates batches
with compiled kernels (``_kernels.py``).  :mod:`.natural_frequencies` holds
the natural-frequency rule shared by identification and predictions, and
:mod:`.modes` finds every mode of an FRF in a band, matches model and
measured modes one to one and tracks each through posterior draws (so that
mode k is only ever compared with mode k).
"""

from .assembly import CachedConfiguration, Configuration, ConfigurationStack, ToolPointModel
from .coupling import attach, contact_compliance, couple, elastic_coupling, inv2, rigid_coupling
from .geometry import Holder, HolderSegment, Tool, ToolSegment, holder_segments, tool_overhang_segments
from .materials import Material
from .receptance import FRF, PointReceptance
from .sections import SectionProperties, circular_section, composite_section, cowper_shear_coefficient
from .timoshenko import Segment, TwoPort, free_free_receptances, segment_dynamic_stiffness

__all__ = [
    "CachedConfiguration", "Configuration", "ConfigurationStack", "ToolPointModel",
    "attach", "contact_compliance", "couple", "elastic_coupling", "inv2", "rigid_coupling",
    "Holder", "HolderSegment", "Tool", "ToolSegment", "holder_segments", "tool_overhang_segments",
    "Material", "FRF", "PointReceptance",
    "SectionProperties", "circular_section", "composite_section", "cowper_shear_coefficient",
    "Segment", "TwoPort", "free_free_receptances", "segment_dynamic_stiffness",
]
