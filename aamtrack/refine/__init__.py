"""refine: RBF deformation, key point sampler, GMM registration and facial transfer (Akagi et al.)."""

from .gmm import GmmConfig, GmmResult, gauss_transform, register
from .rbf import RbfDeformation, fit_rbf, rbf_system
from .sampler import KeyPoints, SamplerConfig, deform_frames, motion_correlation, refine_key_points
from .transfer import TransferConfig, TransferResult, transfer

__all__ = [
    "GmmConfig",
    "GmmResult",
    "KeyPoints",
    "RbfDeformation",
    "SamplerConfig",
    "TransferConfig",
    "TransferResult",
    "deform_frames",
    "fit_rbf",
    "gauss_transform",
    "motion_correlation",
    "rbf_system",
    "refine_key_points",
    "register",
    "transfer",
]
