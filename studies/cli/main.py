"""The ``hingelab`` command line: one thin entry point over the library.

Each subcommand lives in its own ``studies/cli/<command>.py`` module exposing
``register(subparsers) -> None``; the module sets ``func(args) -> int`` as the
parser default. Project errors are caught here, at the boundary, and printed as
one clear message on stderr with exit status 1.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sqlite3
import sys
from typing import Any

from cad.errors import HingelabError

SUBCOMMAND_MODULES = (
    "studies.cli.mesh",
    "studies.cli.cycle",
    "studies.cli.rsm",
    "studies.cli.trace",
    "studies.cli.sweep",
    "studies.cli.study",
    "studies.cli.compare",
    "studies.cli.synth",
    "studies.cli.import_records",
    "studies.cli.diagnose",
    "studies.cli.calibrate",
    "studies.cli.reduce",
    "studies.cli.export_inp",
    "studies.cli.repeatability",
    "studies.cli.paper",
    "studies.cli.report",
)


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser with every available subcommand registered."""
    parser = argparse.ArgumentParser(
        prog="hingelab",
        description="Hysteresis of precision space hinges: CAD → hex mesh → contact FE → response surfaces.",
    )
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="log progress (and Dask's logs) to stderr"
    )
    parser.add_argument("--version", action=_Version)
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for name in SUBCOMMAND_MODULES:
        importlib.import_module(name).register(sub)
    return parser


CHATTY_LIBRARIES = ("build123d", "matplotlib", "PIL", "pyvista", "numexpr")
"""Third-party loggers kept at WARNING even with -v (build123d logs every face it makes)."""


class _Version(argparse.Action):
    """``--version``: hingelab's version and its source digest, read only when asked."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: Any) -> None:
        super().__init__(
            option_strings,
            dest,
            nargs=0,
            default=argparse.SUPPRESS,
            help="print hingelab's version and the digest of its source (model.code), and exit",
        )

    def __call__(self, parser: argparse.ArgumentParser, *args: Any) -> None:
        from model.code import ALL_PACKAGES, code_version

        print(f"hingelab {code_version(ALL_PACKAGES).short()}")
        parser.exit()


def _os_message(err: OSError) -> str:
    """One line naming the path and what went wrong (``[Errno 13] ...`` without the errno)."""
    what = err.strerror or str(err)
    where = err.filename if err.filename is not None else ""
    return f"{where}: {what}" if where else what


def _in_user_terms(err: HingelabError, args: argparse.Namespace) -> HingelabError:
    """The error naming the option the user typed (the command module's ``FIELD_OPTIONS``)."""
    from cad.errors import ParameterError
    from studies.cli.args import in_user_terms

    if not isinstance(err, ParameterError):
        return err
    options = getattr(sys.modules[args.func.__module__], "FIELD_OPTIONS", {})
    return in_user_terms(err, args, options)


def main(argv: list[str] | None = None) -> int:
    """Run the command line; return the process exit status.

    A command whose ``--out`` is a folder (a result folder) gets its command line appended
    to ``commands.jsonl`` there when it ends (``studies.outputs.record_command``), with
    its exit status, so ``hingelab report`` shows the command that really ran.
    """
    typed = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(typed)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    for name in CHATTY_LIBRARIES:  # their INFO lines say nothing a user can act on
        logging.getLogger(name).setLevel(logging.WARNING)
    status = _run(args)
    _record(args, typed, status)
    return status


def _run(args: argparse.Namespace) -> int:
    try:
        return int(args.func(args))
    except HingelabError as err:
        print(f"hingelab {args.command}: error: {_in_user_terms(err, args)}", file=sys.stderr)
        return 1
    except (
        OSError
    ) as err:  # a read-only folder, a full disk, a missing file: one line, no traceback
        print(f"hingelab {args.command}: error: {_os_message(err)}", file=sys.stderr)
        return 1
    except sqlite3.Error as err:
        print(f"hingelab {args.command}: error: database: {err}", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        print(
            f"hingelab {args.command}: interrupted; every finished point is kept "
            "(rerun the same command to resume)",
            file=sys.stderr,
        )
        return 130


def _record(args: argparse.Namespace, typed: list[str], status: int) -> None:
    """Append the command line to its result folder (``--out DIR``), if it has one."""
    from pathlib import Path

    from studies.outputs import COMMANDS_FILE, record_command

    out = getattr(args, "out", None)
    if not isinstance(out, Path) or not out.is_dir() or getattr(args, "dry_run", False):
        return  # no result folder (a file, none, or a dry run that wrote nothing)
    if not any(p.name != COMMANDS_FILE for p in out.iterdir()):
        return  # the command wrote nothing there (refused before any work)
    try:
        record_command(out, typed, status)
    except OSError as err:  # the results are there; a read-only folder only loses the line
        logging.getLogger(__name__).warning("could not record the command in %s: %s", out, err)


if __name__ == "__main__":
    raise SystemExit(main())
