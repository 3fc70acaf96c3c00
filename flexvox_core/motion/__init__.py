"""Motion-aware reconstruction (the paper's Section 4): flow-driven diffusion tensor fields."""

from flexvox_core.motion.mcnc import motion_compensated_nc
from flexvox_core.motion.pipeline import MotionAwareResult, motion_aware
from flexvox_core.motion.streaming import StreamFrame, StreamingMotionAware
from flexvox_core.motion.tensors import DEFAULT_C, resolution_map, tensor_field
from flexvox_core.motion.vardiff import variable_tensor_diffusion

__all__ = [
    "DEFAULT_C",
    "MotionAwareResult",
    "StreamFrame",
    "StreamingMotionAware",
    "motion_aware",
    "motion_compensated_nc",
    "resolution_map",
    "tensor_field",
    "variable_tensor_diffusion",
]
