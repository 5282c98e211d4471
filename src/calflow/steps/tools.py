"""The core's steps around the campaigns: the index, a stage's history, checking a
certificate, importing recordings, checking files and configuration, the controller emulator
and the coded pattern (:class:`calflow.step.Step`, one each)."""

from __future__ import annotations

from calflow.configuration import layout
from calflow.step import CAMPAIGN, OUT, Option, Step

_STUDY_DIR = "config/campaigns"

# fmt: off
STEPS: tuple[Step, ...] = (
    Step(
        "index",
        "render reports/index.html over every campaign on disk (reruns none)",
        "calflow.commands.files:index",
        (
            Option("--results", "the results folder (default: results)", "path", default=layout.RESULTS),
            Option("--reports", "the reports folder (default: reports)", "path", default=layout.REPORTS),
            Option(
                "--campaign-dir",
                "campaign files, to tell whether a report is current (default: config/campaigns)",
                "path",
                default=_STUDY_DIR,
            ),
            Option("--out", "default: <reports>/index.html", "path"),
        ),
        inputs=("summary", "report", "history"),
        writes=("index",),
    ),
    Step(
        "history",
        "write a stage's history.json",
        "calflow.lifecycle.commands:run_history",
        (
            Option("--stage", "the stage's id (campaign key 'stage')", required=True),
            Option(
                "--summaries",
                "the summary.json of every campaign of the stage on disk (results/<campaign>/summary.json); "
                "none when every campaign of the stage has gone",
                "path",
                many="*",
                default=[],
            ),
            Option(
                "--campaigns",
                "their campaign files, in the same order (default: <campaign-dir>/<campaign>.yaml)",
                "path",
                many="+",
            ),
            Option("--campaign-dir", "the folder of the campaign files", "path", default=_STUDY_DIR),
            Option("--results", "the results folder the summaries are in", "path", default=layout.RESULTS),
            Option("--settings", "JSON: the stage's settings (config 'stages.<id>')", "json", default="{}"),
            Option(
                "--out",
                "history.json; an earlier one there is read first (the campaigns that left it, and "
                "what it knew of campaigns without a campaign file)",
                "path",
                required=True,
            ),
        ),
        inputs=("summary", "history"),
        writes=("history",),
    ),
    Step(
        "history-report",
        "render a stage's history report (HTML and PDF)",
        "calflow.lifecycle.commands:run_report",
        (
            Option("--history", required=True, kind="path"),
            Option("--html", required=True, kind="path"),
            Option("--pdf", kind="path"),
        ),
        inputs=("history",),
        writes=("stage_history",),
    ),
    Step(
        "verify-certificate",
        "check a certificate (PDF or DCC): its signature and chain, and that its values equal the results on disk",
        "calflow.certificate.verify:run",
        (
            Option("file", "the certificate's PDF or DCC (reports/<campaign>/certificate.pdf or .xml)", "path"),
            Option("--trust", "PEM file of the CA certificate(s) the signer's chain must reach", "path"),
            Option("--summary", "the results it certifies (default: results/<campaign>/summary.json)", "path"),
        ),
        inputs=("certificate", "summary"),
    ),
    Step(
        "import-csv",
        "turn a CSV recording into a run dataset with a column mapping",
        "calflow.commands.files:import_csv",
        (
            Option("csv", kind="path"),
            Option("--mapping", "YAML file: which column gives which run variable (docs/data.md)", "path", required=True),
            CAMPAIGN,
            OUT,
        ),
        writes=("run",),
    ),
    Step(
        "import-recording",
        "turn an instrument's file (ISO 230-2 .dat, laser-tracker CSV) into a run dataset",
        "calflow.commands.files:import_recording",
        (
            Option("file", kind="path"),
            Option(
                "--format",
                "docs/data.md, 'Recorded campaigns'",
                required=True,
                choices=("ecmc_iso230", "laser_tracker", "csv"),
            ),
            Option("--mapping", "column mapping of a csv recording", "path"),
            Option("--plan", "the run's plan (e.g. metrology, training)", required=True),
            CAMPAIGN,
            OUT,
        ),
        writes=("run",),
    ),
    Step(
        "validate",
        "check netCDF files against the calflow data contract",
        "calflow.commands.files:validate",
        (Option("files", kind="path", many="+"),),
    ),
    Step(
        "check-config",
        "validate config/config.yaml and its campaign files",
        "calflow.commands.files:check_config",
        (
            Option("config", kind="path", many="?", default="config/config.yaml"),
            Option("--campaign-dir", kind="path"),
        ),
    ),
    Step(
        "emulate",
        "serve a campaign's stages as a PI GCS 2.0 controller on 127.0.0.1, with the emulator "
        "its robot family registers (docs/gcs.md)",
        "calflow.gcs.emulation.campaign_server:emulate_command",
        (
            Option("kind", choices=("gcs",)),
            Option("rest", "--campaign FILE [--port 50000] [--time-scale 1] [--duration S]", "rest"),
        ),
    ),
    Step(
        "pattern",
        "an encoded dot pattern: its file, GDSII and preview (docs/instruments.md)",
        "calflow.instruments.pattern.commands:run_pattern",
        (
            Option(
                "action", "make: write a pattern file, its GDSII for lithography and a PNG preview",
                choices=("make",), metavar="make",
            ),
            Option("--range", "measuring range, e.g. 9500x4200", required=True, metavar="XxY", units="um"),
            Option(
                "--layout", "cell2x2 (calflow's, default) or megarena (FEMTO-ST's)",
                choices=("cell2x2", "megarena"), default="cell2x2",
            ),
            Option("--period-um", "dot pitch; default 4 for cell2x2, 9 for megarena", "float", units="um"),
            Option("--dot-um", "dot diameter; default half the period", "float", units="um"),
            Option("--depth", "megarena: code depth, 4 to 12 (default: the smallest that covers the range)", "int"),
            Option("--out", "folder for pattern.json, pattern.gds, pattern.png", "path", required=True),
            Option("--name", "file stem (default: pattern)", default="pattern"),
        ),
    ),
    Step(
        "decode",
        "decode frames of an encoded pattern into x, y, Θ (docs/instruments.md)",
        "calflow.instruments.pattern.commands:run_decode",
        (
            Option("frames", "image files: TIFF (one frame or a stack) or PNG, monochrome", "path", many="+"),
            Option(
                "--pattern",
                "the pattern file: calflow's (calflow pattern make) or the Vernier library's "
                "MegarenaPattern or HPCodePattern JSON (HP-code markers: one CSV row per marker)",
                "path", required=True,
            ),
            Option(
                "--pixel-um",
                "pixel size in the object plane (cell2x2 default: the default camera's; "
                "megarena and hpcode default: measured from each frame)",
                "float", units="um",
            ),
            Option(
                "--pixel-size",
                "hpcode without --pixel-um: each frame's own pixel size (frame, default) or one pooled "
                "over the frames, with its uncertainty from their scatter and a test for drift (sequence)",
                choices=("frame", "sequence"), default="frame",
            ),
            Option(
                "--fit-region",
                "megarena: central fraction of the frame the phase planes are fitted on (1: whole frame "
                "but the window's tapered tenth of each side; 0.5 as the Vernier library; default: the "
                "convention's, 1 for calflow, 0.5 for vernier)",
                "float",
            ),
            Option(
                "--plane-weights",
                "megarena: the phase planes' weights, the lobe's power (power: the least noise) or equal "
                "(uniform: the library's mean lattice); default: the convention's, power for calflow, "
                "uniform for vernier",
                choices=("power", "uniform"),
            ),
            Option(
                "--convention",
                "megarena, hpcode: poses in calflow's convention or as the Vernier library prints them "
                "(x, y, alpha, pixelSize; docs/instruments.md); megarena's vernier is also the library's "
                "estimand (--fit-region 0.5 --plane-weights uniform unless given)",
                choices=("calflow", "vernier"), default="calflow",
            ),
            Option("--jobs", "processes decoding frames (default: every core)", "int", default=0),
            Option("--out", "poses.csv or poses.nc (default: print CSV)", "path"),
        ),
    ),
)
# fmt: on
