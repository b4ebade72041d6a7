"""``skinsynth precompile``: build every compiled loop and CPU kernel ahead of use (one install step)."""

import time

import click

from .common import report, summary_options, user_errors


@click.command("precompile")
@click.option("--influences", "-k", "influences", multiple=True, type=int, default=(4,), show_default=True,
              help="Build the skinning kernels for skins of this many influences per vertex (fit-skin's "
                   "--max-influences; repeat for several). Other values compile on first use.")
@summary_options
@user_errors
def precompile(influences, quiet, as_json):
    """Compile every numba loop and every warp CPU kernel the commands use, into the caches they load.

    A command's first run otherwise compiles them itself (fit-skin: about 15 s, play and export:
    a few seconds each); run this once after installing (make setup does), e.g. as a Dockerfile
    RUN step, so that every later command starts warm. Running it again only loads what is
    already built (a few seconds), so it also checks the caches.

    Where the results go (the caches the commands then read):

    \b
      numba loops  $NUMBA_CACHE_DIR when set; else __pycache__ beside skinsynth's sources; if that
                   folder is not writable (a read-only install), numba's user-wide cache folder
                   (~/.cache/numba)
      warp kernels $SKINSYNTH_CACHE_DIR when set; else ~/.cache/skinsynth/warp

    Precompile and run with the same environment (in a Dockerfile: ENV before the RUN step; farm
    nodes and Dask workers: the same variables, or a shared image). numba only loads from a folder
    it can write to, so precompile as the user who runs the commands, or point NUMBA_CACHE_DIR at
    a folder that user can write. Entries are keyed by the CPU (numba: its
    name and features; warp: LLVM version and target): a different CPU compiles its own, never
    loading a wrong binary. --device cuda kernels are built on first use.

    \b
    Examples:
      skinsynth precompile
      NUMBA_CACHE_DIR=/opt/skinsynth/cache SKINSYNTH_CACHE_DIR=/opt/skinsynth/cache skinsynth precompile --json
    """
    from skinsynth.gpu import compile_cpu_kernels
    from skinsynth.pipeline.errors import OptionError
    from skinsynth.pipeline.runtime.compiled import compiled_line, compiled_summary
    from skinsynth.pipeline.skin import compile_loops as skin_loops
    from skinsynth.pipeline.synthesis import compile_loops as synthesis_loops
    from skinsynth.pipeline.view import compile_loops as view_loops

    if any(k < 1 for k in influences):
        raise OptionError(f"--influences must be at least 1 (got {min(influences)})")
    talk = not (quiet or as_json)
    start = time.perf_counter()
    items = []

    def done(item):
        items.append(item)
        if talk:
            click.echo(compiled_line(item))

    done(skin_loops())
    done(view_loops())
    done(synthesis_loops())
    compile_cpu_kernels(tuple(dict.fromkeys(influences)), done=done)
    report(*compiled_summary(items, time.perf_counter() - start), as_json=as_json, quiet=quiet)
