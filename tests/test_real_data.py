"""Slow tests on the real sequences in ../shared/data (skipped, with the reason, when absent)."""

import numpy as np
import pytest

from skinsynth.formats.errors import FormatError
from skinsynth.formats.meshseq import read_mesh_sequence
from skinsynth.gpu import lbs_reference
from skinsynth.pipeline.skin_fit import bounding_box_diagonal, fit_skin

pytestmark = pytest.mark.slow


def _sequences(root):
    for folder in sorted(p for p in root.iterdir() if p.is_dir()):
        for spec in [folder] + sorted(folder.rglob("*")):
            if spec.is_dir() or spec.suffix.lower() in (".usd", ".usda", ".usdc", ".npz", ".h5"):
                try:
                    yield folder.name, read_mesh_sequence(str(spec))
                    break
                except FormatError:
                    continue


def test_real_sequences_fit_with_valid_weights(shared_data):
    fitted = 0
    for name, seq in _sequences(shared_data):
        frames = seq.vertices[: min(len(seq.vertices), 40)]
        fit = fit_skin(frames, bones=12, iterations=8)
        recon = lbs_reference(fit.rest_vertices, fit.bone_indices, fit.bone_weights, fit.rotations, fit.translations)
        rmse = np.sqrt(np.mean(np.sum((recon - frames) ** 2, axis=2))) / bounding_box_diagonal(frames[0])
        assert np.all(fit.bone_weights >= 0) and np.allclose(fit.bone_weights.sum(axis=1), 1.0), name
        assert fit.rotations.shape[1] == 12, name
        assert rmse < 0.05, f"{name}: RMSE/diag {rmse:.4f}"
        fitted += 1
    assert fitted > 0, f"no readable sequence under {shared_data}"
