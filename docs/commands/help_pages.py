"""Every command's page in docs/commands/ ends with the command's own ``--help``, exactly as
``skinsynth COMMAND --help`` prints it in a terminal 100 columns wide (or wider: the CLI wraps at
100), between two markers:

    <!-- begin: skinsynth COMMAND --help (python docs/commands/help_pages.py writes it) -->
    ```text
    …
    ```
    <!-- end: skinsynth COMMAND --help -->

``docs/commands/index.md`` holds ``skinsynth --help`` the same way. The text comes from the live
command (click's own help, run in-process), so the pages never drift from it:

    python docs/commands/help_pages.py          # rewrite every block; start a page for a new command
    python docs/commands/help_pages.py --check  # exit 1, naming each page that differs or is missing

``tests/contracts/test_docs.py`` runs the check in ``make test``.
"""

import argparse
import os
import pathlib
import re
import sys

COMMANDS_DIR = pathlib.Path(__file__).resolve().parent
#: The terminal width the blocks are rendered at (the CLI's own max_content_width is 100).
COLUMNS = 100


def commands():
    """The names of skinsynth's subcommands, sorted."""
    from skinsynth.cli.main import main

    return sorted(main.commands)


def help_text(command=None):
    """What ``skinsynth [COMMAND] --help`` prints in a terminal COLUMNS wide: the command's own
    entry point, run in-process with its stdout captured (click's test runner would force 80)."""
    import contextlib
    import io

    from skinsynth.cli.main import main

    args = [command, "--help"] if command else ["--help"]
    out = io.StringIO()
    columns = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(COLUMNS)
    try:
        with contextlib.redirect_stdout(out):
            main.main(args, prog_name="skinsynth")
    except SystemExit as done:
        if done.code not in (0, None):
            raise RuntimeError(f"skinsynth {' '.join(args)} exited {done.code}") from None
    finally:
        if columns is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = columns
    return out.getvalue()


def page_path(command=None):
    return COMMANDS_DIR / (f"{command}.md" if command else "index.md")


def _markers(command):
    name = f"skinsynth {command} --help" if command else "skinsynth --help"
    return (f"<!-- begin: {name} (python docs/commands/help_pages.py writes it) -->",
            f"<!-- end: {name} -->")


def block(command=None):
    """The marked block a page holds for COMMAND (None: the group)."""
    begin, end = _markers(command)
    return f"{begin}\n```text\n{help_text(command).rstrip()}\n```\n{end}"


def _pattern(command):
    begin, end = _markers(command)
    return re.compile(re.escape(begin) + r".*?" + re.escape(end), re.S)


def problems():
    """One line per page that is missing, lacks its block, holds a stale one, or names no command."""
    found = []
    names = commands()
    for command in [None, *names]:
        path = page_path(command)
        label = f"skinsynth {command + ' ' if command else ''}--help"
        if not path.exists():
            found.append(f"{path.relative_to(COMMANDS_DIR.parent.parent)}: missing (the page of {label})")
            continue
        text = path.read_text(encoding="utf-8")
        matches = _pattern(command).findall(text)
        if len(matches) != 1:
            found.append(f"{path.relative_to(COMMANDS_DIR.parent.parent)}: holds {len(matches)} blocks of "
                         f"{label}, not one")
        elif matches[0] != block(command):
            found.append(f"{path.relative_to(COMMANDS_DIR.parent.parent)}: its block differs from {label}")
    for path in sorted(COMMANDS_DIR.glob("*.md")):
        if path.stem != "index" and path.stem not in names:
            found.append(f"{path.relative_to(COMMANDS_DIR.parent.parent)}: no command {path.stem!r}")
    return found


def write():
    """Rewrite every page's block; a command without a page gets a new one holding its block."""
    for command in [None, *commands()]:
        path = page_path(command)
        if not path.exists():
            title = f"`skinsynth {command}`" if command else "Commands"
            path.write_text(f"# {title}\n\n## `--help`\n\n{block(command)}\n", encoding="utf-8")
            print(f"wrote {path} (new: add it to mkdocs.yml's nav and write its manual)")
            continue
        text = path.read_text(encoding="utf-8")
        pattern = _pattern(command)
        if pattern.search(text):
            new = pattern.sub(lambda _: block(command), text, count=1)
        else:
            new = text.rstrip("\n") + f"\n\n## `--help`\n\n{block(command)}\n"
        if new != text:
            path.write_text(new, encoding="utf-8")
            print(f"updated {path}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="change nothing; exit 1 naming each stale page")
    opts = parser.parse_args()
    if opts.check:
        found = problems()
        for line in found:
            print(line, file=sys.stderr)
        if found:
            print("run: python docs/commands/help_pages.py", file=sys.stderr)
        return 1 if found else 0
    write()
    return 0


if __name__ == "__main__":
    sys.exit(main())
