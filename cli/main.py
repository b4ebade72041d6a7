"""The ``skinsynth`` command: one click group, one module per subcommand."""

import click

from .common import tool_version
from .example import example
from .export import export
from .fit_skin import fit_skin
from .inspect_file import inspect_file


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(tool_version(), prog_name="skinsynth")
def main():
    """Example-based mesh animation: fit a skinned model to a mesh sequence, then export it.

    Stages read and write self-contained HDF5 model files, so they chain like Makefile rules:

    \b
      skinsynth example bending-bar -o bar.npz
      skinsynth fit-skin bar.npz -o skin.h5 --bones 8
      skinsynth inspect skin.h5
      skinsynth export skin.h5 -o skin.usdc --as skel
    """


main.add_command(fit_skin)
main.add_command(inspect_file)
main.add_command(export)
main.add_command(example)
