"""``skinsynth inspect``: what a model file holds."""

import json

import click

from .common import user_errors


@click.command("inspect")
@click.argument("path", type=click.Path(dir_okay=False))
@click.option("--json", "as_json", is_flag=True, help="Print one JSON object instead of text.")
@click.option("--quiet", "-q", is_flag=True, help="Print nothing: only check the file (exit 0 when it is valid, 2 if not).")
@click.option("--digests", is_flag=True,
              help="Also the sha256 of every dataset and attribute (provenance aside): two files with the same "
                   "digests hold the same data bit for bit, however stored (e.g. --jobs against --cluster).")
@user_errors
def inspect_file(path, as_json, quiet, digests):
    """Summarise a skinsynth model file: stage, version, counts, clips, fit errors, provenance.

    The clips are the takes the examples hold, in order (fit-skin CLIP...): each one's name, frame
    count and first and last frame in the file's one frame numbering (a file from before clips
    were stored is one clip, named after its source).

    \b
    Examples:
      skinsynth inspect horse.skin.h5
      skinsynth inspect horse.skin.h5 --json | jq .rmse_over_diagonal
    """
    from skinsynth.formats.hdf5_storage import BLOCK_BYTES
    from skinsynth.formats.inspection import describe_model, description_lines
    from skinsynth.formats.model import content_digests, read_model

    # a dataset larger than a block is checked block by block: a file of any size in bounded memory
    summary = describe_model(path, read_model(path, summarise_above=BLOCK_BYTES))
    if digests:
        summary["digests"] = content_digests(path)
    if quiet and not as_json:
        return
    if as_json:
        click.echo(json.dumps(summary, sort_keys=True, default=str))
        return
    for line in description_lines(summary):
        click.echo(line)
