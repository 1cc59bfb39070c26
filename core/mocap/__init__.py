"""Motion-capture files: Acclaim ASF/AMC (CMU variant) and frame-rate resampling."""

from .errors import MocapParseError
from .asf import AsfBone, AsfSkeleton, format_asf, parse_asf, read_asf, write_asf
from .acclaim_skeleton import YUP_TO_ZUP, ChannelLayout, asf_to_skeleton, channel_layout
from .amc import AmcMotion, format_amc, parse_amc, read_amc, read_amc_steps, run_steps, write_amc
from .resample import resample
from .bvh import CMU_BVH_NAMES, asf_dofs_from_world_deltas, cmu_template_asf, fill_unmapped, \
    format_bvh, world_deltas_from_asf_dofs

__all__ = [
    "CMU_BVH_NAMES",
    "AmcMotion",
    "AsfBone",
    "AsfSkeleton",
    "ChannelLayout",
    "MocapParseError",
    "YUP_TO_ZUP",
    "asf_dofs_from_world_deltas",
    "asf_to_skeleton",
    "cmu_template_asf",
    "fill_unmapped",
    "format_bvh",
    "channel_layout",
    "format_amc",
    "format_asf",
    "parse_amc",
    "parse_asf",
    "read_amc",
    "read_amc_steps",
    "read_asf",
    "resample",
    "run_steps",
    "write_amc",
    "world_deltas_from_asf_dofs",
    "write_asf",
]
