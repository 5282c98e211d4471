"""The ``calflow`` command line: one subcommand per workflow step.

Every rule of the Snakemake workflow calls one subcommand. Errors the user can fix are
printed as one line (``calflow: error: <file>: <field>: <what was expected>``) with a
non-zero exit status; outputs are written atomically, so a failed step leaves none.
"""

from __future__ import annotations

import argparse
import os
import sys

from calflow import __version__, footprint
from calflow.errors import CalflowError
from calflow.step import KINDS, Job, Option
from calflow.steps import entry_point, entry_points, options_of, steps

__all__ = ["entry_point", "entry_points", "main", "parser"]


def _run(target: str):
    """A subcommand function that imports ``"module:function"`` only when it runs."""

    def run(args):
        from calflow.family import resolve

        return resolve(target)(args)

    run.target = target
    return run


def add_option(p: argparse.ArgumentParser, o: Option) -> None:
    """Option ``o`` (:class:`calflow.step.Option`) on parser ``p``."""
    help_ = f"{o.help} ({o.units})" if o.units and o.help else (f"({o.units})" if o.units else o.help)
    kw: dict = {"help": help_ or None}
    if o.kind == "flag":
        kw["action"] = "store_true"
    elif o.kind == "rest":
        kw["nargs"] = argparse.REMAINDER
    else:
        if KINDS[o.kind] is not str:
            kw["type"] = KINDS[o.kind]
        if o.many == "append":
            kw["action"] = "append"
        elif o.many:
            kw["nargs"] = o.many
        if o.default is not None:
            kw["default"] = o.default
        if o.choices:
            kw["choices"] = list(o.choices)
        if o.metavar:
            kw["metavar"] = o.metavar
    if not o.positional and o.required:
        kw["required"] = True
    p.add_argument(o.name, **kw)


def parser() -> argparse.ArgumentParser:
    """The command line: one subcommand per step (:func:`calflow.steps.steps`), its options
    those the step declares (and those the families add to it)."""
    p = argparse.ArgumentParser(prog="calflow", description=__doc__.splitlines()[0])
    p.add_argument("--version", action="version", version=f"calflow {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    for s in steps():
        q = sub.add_parser(s.name, help=s.help)
        q.set_defaults(func=_run(s.run))
        for o in options_of(s.name):
            add_option(q, o)
        if s.reads_campaign:  # a step that reads a campaign reads only what its rule hands it
            q.add_argument("--sections", help=SECTIONS_HELP)
    return p


SECTIONS_HELP = (
    "the campaign sections this step reads, comma-separated (its rule hands them and digests the "
    "same); reading another is an error; '*': all of them. Default: all"
)


def _error(message: str) -> int:
    """Print ``calflow: error: <message>`` on stderr, and on the file descriptor named by
    ``CALFLOW_ERROR_FD`` too: the workflow's jobs send stderr to their log, and pass the
    terminal's stderr as that descriptor so the one line reaches the user (common.smk)."""
    line = f"calflow: error: {message}"
    print(line, file=sys.stderr)
    fd = os.environ.get("CALFLOW_ERROR_FD", "")
    if fd.isdigit():
        try:
            os.write(int(fd), (line + "\n").encode())
        except OSError:  # not open in this process: stderr has it
            pass
    return 2


def _step(args) -> int:
    """Run the step the command line names, handed its :class:`calflow.step.Job`."""
    job = Job.of(args.command, **{k: v for k, v in vars(args).items() if k not in ("func", "command")})
    try:
        status = args.func(job)
    except (CalflowError, ValueError) as exc:  # library ValueErrors are worded for users
        return _error(str(exc))
    except OSError as exc:  # a file or folder the system refused: name it, no traceback
        return _error(f"{exc.filename}: {exc.strerror or exc}" if exc.filename else str(exc.strerror or exc))
    except KeyboardInterrupt:
        print("calflow: interrupted; no output was written", file=sys.stderr)
        return 130
    return int(status or 0)


def main(argv: list[str] | None = None) -> int:
    """Run one subcommand; a workflow job then records its own peak memory and CPU time
    (:mod:`calflow.footprint`)."""
    args = parser().parse_args(argv)
    status = 1  # an uncaught exception (a traceback) is recorded as a failure
    try:
        status = _step(args)
    finally:
        footprint.finish(args.command, status)
    return status


if __name__ == "__main__":
    sys.exit(main())
