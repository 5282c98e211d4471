"""The core's steps of a campaign: acquire, decode a frame recording, identify, metrics, the
summary, the report and the certificate (:class:`calflow.step.Step`, one each)."""

from __future__ import annotations

from calflow.step import ALL, CAMPAIGN, OUT, Option, Step

_SUMMARY_SETTINGS = "JSON: the stage's settings (config 'stages.<id>'): specification, decision rule"

# fmt: off
STEPS: tuple[Step, ...] = (
    Step(
        "acquire",
        "run a plan on the campaign's rig and write the run dataset",
        "calflow.commands.acquire:run",
        (
            CAMPAIGN,
            Option("--plan", required=True),
            Option("--model", "model file(s) whose inverse commands the run", "path", many="append"),
            OUT,
            Option("--truth", "where to write the rig's truth (simulated rigs), for tests and reports", "path"),
            Option("--decoded", "a frame recording's decoded run (calflow decode-run), for a replay rig", "path"),
            Option(
                "--rig-plugins",
                "comma-separated modules whose 'module:callable' rig factories may run "
                "(default: $CALFLOW_RIG_PLUGINS; the workflow passes config rig_plugins)",
                metavar="MODULES",
            ),
        ),
        reads=("seed", "rig"),
        reads_per_job="the sections of the run's plan (its family's `open_loop_runs`)",
        inputs=("model", "luts", "decoded"),
        writes=("run", "truth"),
    ),
    Step(
        "decode-run",
        "decode a replay campaign's recorded camera frames into the run dataset of one run",
        "calflow.commands.decode_run:run",
        (
            CAMPAIGN,
            Option("--run", "the run id of the frame recording (rig.options.recordings)", required=True),
            OUT,
        ),
        reads=("rig",),
        writes=("decoded",),
    ),
    Step(
        "identify",
        "identify one calibration model",
        "calflow.commands.campaign:identify",
        (
            CAMPAIGN,
            Option("--model-name", required=True),
            Option("--run", "the run the model is identified from (its family's identification run)", "path"),
            OUT,
        ),
        reads_per_job="the sections of the model (its family's `identify_sections`)",
        inputs=("run", "luts", "model"),
        writes=("model",),
    ),
    Step(
        "metrics",
        "ISO 9283 accuracy and repeatability of a run",
        "calflow.commands.campaign:metrics",
        (
            CAMPAIGN,
            Option("--run", required=True, kind="path"),
            OUT,
        ),
        inputs=("run",),
        writes=("metrics",),
    ),
    Step(
        "summarise",
        "write the campaign's summary.json",
        "calflow.commands.campaign:summarise",
        (
            CAMPAIGN,
            Option("--files", "the campaign's model, metrics and table files", "path", required=True, many="+"),
            Option("--truth", kind="path"),
            Option("--budget", "the error budget's replays (calflow error-budget), simulated rigs", "path"),
            Option("--settings", _SUMMARY_SETTINGS, "json"),
            OUT,
        ),
        reads=(ALL,),
        inputs=("model", "metrics", "luts", "truth"),
        writes=("summary",),
    ),
    Step(
        "report",
        "render the campaign report (HTML and PDF)",
        "calflow.commands.campaign:report",
        (
            CAMPAIGN,
            Option("--summary", required=True, kind="path"),
            Option("--files", "run, table and metrics files the figures draw on", "path", many="*"),
            Option("--html", required=True, kind="path"),
            Option("--pdf", kind="path"),
        ),
        reads=(ALL,),
        inputs=("summary", "run", "metrics", "luts"),
        writes=("report",),
    ),
    Step(
        "certificate",
        "render a campaign's certificate (HTML and PDF): U, decisions, as found and as left",
        "calflow.certificate.page:run",
        (
            CAMPAIGN,
            Option("--summary", required=True, kind="path"),
            Option("--html", required=True, kind="path"),
            Option("--pdf", kind="path"),
            Option("--xml", "the Digital Calibration Certificate (DCC, PTB's XML schema)", "path"),
            Option("--laboratory", "JSON: config 'laboratory' (name, address, accreditation, approver, signing_key)", "json"),
            Option("--item", "JSON: config 'stages.<id>.item' (customer, manufacturer, model, serial_number)", "json"),
        ),
        reads=(ALL,),
        inputs=("summary",),
        writes=("certificate",),
    ),
)
# fmt: on
