"""A workflow step, declared once: what ``calflow <step>`` reads, writes, takes and runs.

One :class:`Step` per subcommand, the core's (:mod:`calflow.steps`) and the families'
(``Family.commands``). From it follow the command line (``calflow <step> --help``,
:func:`calflow.cli.parser`), the campaign sections a workflow job is handed and digested
(``reads(step, ...)`` in workflow/rules/common.smk), the code its rerun digest covers
(:func:`calflow.provenance.code_digest` starts at :attr:`Step.run`) and docs/steps.md.

A declaration is data: the function is named as ``"module:function"`` and imported only when
the step runs, so reading every declaration (``calflow --help``, the Snakefile) loads no
numerical library. The function is called with the parsed options, ``run(args)``, and returns
an exit status or None.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

#: What every step that reads a campaign reads: the robot (it names the family) and the start,
#: which every file a step writes is stamped with (:func:`calflow.data.runs.meta`).
STAMP = ("robot", "start")

#: The key of a step that reads the whole campaign (the summary, the report): it is handed all
#: of it, sections the file leaves out included, and its digest covers all of it.
ALL = "*"

#: The kinds of value an option takes: its Python type on the command line.
KINDS = {"text": str, "path": str, "json": str, "int": int, "float": float, "flag": None, "rest": None}


@dataclass(frozen=True)
class Option:
    """One option (``--name``) or positional argument (``name``) of a step.

    ``kind``: one of :data:`KINDS` — ``path`` a file or folder, ``json`` a JSON object given as
    text, ``flag`` present or not, ``rest`` every argument left (handed on as they are);
    ``units``: of a number (``"um"``), shown in ``--help``; ``many``: ``""`` one value, ``"+"``
    one or more, ``"*"`` any number, ``"?"`` an optional positional, ``"append"`` repeatable.
    """

    name: str
    help: str = ""
    kind: str = "text"
    required: bool = False
    many: str = ""
    default: Any = None
    choices: tuple[str, ...] = ()
    units: str = ""
    metavar: str | None = None

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"option {self.name}: kind {self.kind!r}: expected one of {', '.join(KINDS)}")
        if self.many not in ("", "+", "*", "?", "append"):
            raise ValueError(
                f"option {self.name}: many {self.many!r}: expected '', '+', '*', '?' or 'append'"
            )

    @property
    def positional(self) -> bool:
        return not self.name.startswith("-")


#: The two options most steps take: the campaign file the job reads, and the file it writes.
CAMPAIGN = Option("--campaign", required=True, kind="path")
OUT = Option("--out", required=True, kind="path")


@dataclass(frozen=True)
class Step:
    """One step: ``calflow <name>``.

    * ``help``: one line; ``run``: the ``"module:function"`` it runs, ``run(args)``.
    * ``options``: what it takes (:class:`Option`); a step with ``--campaign`` also takes
      ``--sections`` (the sections its rule hands it; reading another is an error).
    * ``reads``: the campaign keys every job of the step reads besides :data:`STAMP`
      (``"validation.heldout"``: one key of a section; :data:`ALL`: the whole campaign);
      ``reads_per_job``: in words, what a rule adds per job (the plan's sections …).
    * ``inputs``, ``writes``: the files it reads and writes, as names of
      :mod:`calflow.configuration.layout` functions (``"run"``: ``layout.run``).
    * A step whose command line names an action (``calflow pattern make``) declares it as a
      positional :class:`Option` with its ``choices``.
    """

    name: str
    help: str
    run: str
    options: tuple[Option, ...] = ()
    reads: tuple[str, ...] = ()
    reads_per_job: str = ""
    inputs: tuple[str, ...] = ()
    writes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        if self.run.count(":") != 1 or not all(self.run.split(":")):
            raise ValueError(f"step {self.name}: run {self.run!r}: expected 'module:function'")
        names = [o.name for o in self.options]
        if len(names) != len(set(names)):
            raise ValueError(f"step {self.name}: an option is declared twice: {names}")

    @property
    def reads_campaign(self) -> bool:
        """Whether the step reads a campaign (takes ``--campaign``)."""
        return any(o.name == "--campaign" for o in self.options)

    def sections(self, *per_job: str) -> list[str]:
        """The campaign keys a job of this step is handed, in order: :data:`STAMP`, the
        step's :attr:`reads`, then ``per_job`` (what its rule adds), each once."""
        return list(dict.fromkeys([*STAMP, *self.reads, *per_job]))


@dataclass(frozen=True)
class Job:
    """What one run of a step hands its function and the family's hooks it calls: the step's
    name and the values of its declared options (files by their option's name, where it writes
    as ``out``), read-only. ``job.run`` is the value of ``--run``; asking for a name the step
    does not declare is an :class:`AttributeError` naming the step.

    The core builds it from the command line (:func:`calflow.cli.main`) and for the family's
    hooks it calls itself (the summary's truth, the report's figures); a family's code builds
    one to call its own hooks (:meth:`with_values`).
    """

    step: str
    values: Mapping[str, Any]

    def __getattr__(self, name: str) -> Any:
        if name.startswith("__"):
            raise AttributeError(name)
        values = object.__getattribute__(self, "values")
        if name not in values:
            step = object.__getattribute__(self, "step")
            raise AttributeError(f"calflow {step}: no input {name!r}; it has {', '.join(sorted(values))}")
        return values[name]

    def with_values(self, **values: Any) -> Job:
        """The same job with ``values`` set (the loaded truth in place of its file)."""
        return Job(self.step, MappingProxyType({**self.values, **values}))

    @classmethod
    def of(cls, step: str, **values: Any) -> Job:
        return cls(step, MappingProxyType(dict(values)))
