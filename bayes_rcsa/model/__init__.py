"""The physical model: materials and sections, Timoshenko beams, coupling, assembly."""

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
