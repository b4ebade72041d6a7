"""A trained puppet as the plain host arrays its run time needs (numpy only)."""

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class PuppetArrays:
    """What the run time needs of a trained puppet, as plain arrays (host, float64).

    rest_vertices (V, 3); bone_indices, bone_weights (V, K) (zero weight = padding slot);
    training_controls (n_p, d) standardised; kernel one of KERNEL_KINDS with its offset and
    degree (polynomial); predictor (8B, n_p) with row b·8 + m the m-th dual-quaternion number of
    bone b, bias (8B,); the translation operator (``pipeline.poisson.TranslationOperator``):
    rotation_operator Γ (B, B, 3), control_operator Q (B, n_c), prior_operator Π (B, B), or all
    None for a puppet trained without the solver; the pose-space correctives
    (``pipeline.correctives.Correctives``): corrective_weights A (n_p, n_p), corrective_power p,
    corrective_tail B (n_p, 1 + r) and corrective_axes P (r, d) (or None), corrective_offsets
    O (n_p, V, 3); all None without correctives.
    """

    rest_vertices: np.ndarray
    bone_indices: np.ndarray
    bone_weights: np.ndarray
    training_controls: np.ndarray
    kernel: str
    predictor: np.ndarray
    bias: np.ndarray
    rotation_operator: np.ndarray | None = None
    control_operator: np.ndarray | None = None
    prior_operator: np.ndarray | None = None
    offset: float = 0.0
    degree: int = 5
    corrective_weights: np.ndarray | None = None
    corrective_offsets: np.ndarray | None = None
    corrective_power: float = 1.0
    corrective_tail: np.ndarray | None = None
    corrective_axes: np.ndarray | None = None

    @classmethod
    def from_puppet(cls, puppet):
        """From a ``pipeline.puppet.Puppet``."""
        reg, ops, corr = puppet.regression, puppet.translations, puppet.correctives
        bones = reg.predictor.shape[0]
        return cls(rest_vertices=puppet.rest_vertices, bone_indices=puppet.bone_indices,
                   bone_weights=puppet.bone_weights, training_controls=puppet.training_controls,
                   kernel=puppet.kernel.kind, offset=float(puppet.kernel.offset), degree=int(puppet.kernel.degree),
                   predictor=reg.predictor.reshape(bones * 8, -1), bias=reg.bias.reshape(bones * 8),
                   rotation_operator=None if ops is None else ops.rotation_operator,
                   control_operator=None if ops is None else ops.control_operator,
                   prior_operator=None if ops is None else ops.prior_operator,
                   corrective_weights=None if corr is None else corr.weights,
                   corrective_offsets=None if corr is None else corr.offsets,
                   corrective_power=1.0 if corr is None else corr.power,
                   corrective_tail=None if corr is None else corr.tail,
                   corrective_axes=None if corr is None else corr.axes)

    @property
    def bones(self):
        return self.predictor.shape[0] // 8

    @property
    def has_solver(self):
        return self.rotation_operator is not None

    @property
    def has_correctives(self):
        return self.corrective_weights is not None


def host_arrays(puppet):
    """The :class:`PuppetArrays` of a ``pipeline.puppet.Puppet``, of a :class:`PuppetArrays` (itself)
    or of a :class:`~skinsynth.gpu.device_puppet.DevicePuppet` (the arrays it uploaded, its ``host``)."""
    if isinstance(puppet, PuppetArrays):
        return puppet
    if isinstance(getattr(puppet, "host", None), PuppetArrays):
        return puppet.host
    return PuppetArrays.from_puppet(puppet)
