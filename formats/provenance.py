"""Provenance records: what made a file, from what, with which settings."""

import datetime
import glob
import hashlib
import os



def file_sha256(path, block=1 << 20):
    """SHA-256 hex digest of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        for chunk in iter(lambda: handle.read(block), b""):
            digest.update(chunk)
    return digest.hexdigest()


def input_records(paths):
    """[{path, sha256}] for every file in ``paths`` (folders and globs are listed by their files)."""
    records = []
    for path in paths:
        if not os.path.exists(path):
            from .meshseq import natural_key  # numpy: imported by a glob input only, not by every command's start

            records.extend(input_records(sorted(glob.glob(path), key=natural_key)))
        elif os.path.isdir(path):
            records.extend(input_records(sorted(os.path.join(path, n) for n in os.listdir(path))))
        elif os.path.isfile(path):
            records.append({"path": os.path.abspath(path), "sha256": file_sha256(path)})
    return records


def provenance_record(stage, command, parameters, inputs, tool_version, seed=None):
    """One stage's provenance record (the date is the only field that changes run to run)."""
    return {
        "stage": stage,
        "command": command,
        "parameters": parameters,
        "inputs": input_records(inputs),
        "tool_version": tool_version,
        "seed": seed,
        "date": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }
