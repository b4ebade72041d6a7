"""The real sequences under ../shared/data, read as skinsynth reads any input, for the benchmarks.

Each subfolder is one dataset: the folder itself if it holds frame files, else its first
.usd/.npz/.h5 file that reads. When the folder is absent a JSON line says so, and the
benchmarks go on with their built-in procedural stand-ins.
"""

import json
import pathlib

SHARED_DATA = pathlib.Path(__file__).resolve().parents[2] / "shared" / "data"
#: bone counts of the issues' tables (Zheng Table 1 for the horse); others get the caller's default.
BONES = {"horse_gallop": 22, "vlasic_samba": 30, "vellum_sheet": 30}


def shared_sequences():
    """Yield (name, vertices (F, V, 3), faces (T, 3)) for every readable dataset in ../shared/data."""
    from skinsynth.formats.errors import FormatError
    from skinsynth.formats.meshseq import read_mesh_sequence

    if not SHARED_DATA.is_dir():
        print(json.dumps({"dataset": "shared/data", "skipped": f"no real data at {SHARED_DATA}"}), flush=True)
        return
    for folder in sorted(p for p in SHARED_DATA.iterdir() if p.is_dir()):
        for spec in [folder] + sorted(folder.rglob("*")):
            if spec.is_dir() or spec.suffix.lower() in (".usd", ".usda", ".usdc", ".npz", ".h5", ".hdf5"):
                try:
                    sequence = read_mesh_sequence(str(spec))
                except FormatError:
                    continue
                yield folder.name, sequence.vertices, sequence.faces
                break
