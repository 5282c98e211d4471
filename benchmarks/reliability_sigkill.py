"""SIGKILLs at random points of acquisitions, each resumed (docs/reliability.md).

For each rig — the simulated XYΘ rig (slowed down so a kill can land mid-run) and the
``gcs`` rig through the C-863 campaign emulator — one uninterrupted reference run (in this
process, as ``calflow acquire`` would run it), then
chains of ``calflow acquire`` processes killed with SIGKILL at a random time after they
journaled a new sample, each chain resumed by running the same command again until it
completes. Counted per chain:

* ``lost``: samples journaled before a kill that are not, identical, at their place in
  the final dataset, plus plan rows missing from it;
* ``duplicated``: rows beyond the plan's, plus rows whose commands are not the plan's;
* ``journal_never_shrank``: after every kill the journal held at least what it held
  before (nothing acquired is forgotten);
* ``equal_to_uninterrupted``: the simulated rig (replayable) is byte-for-byte the
  reference in every variable; the gcs rig (continued, not replayed) has the reference's
  commands and indices, a monotonic time axis, and measurements within 10 sigma of the
  sensor noise of the reference's (the noise of a second pass differs).

``python benchmarks/reliability_sigkill.py --kills 50 --json`` (about 3-4 min on 2 cores);
``--smoke`` (CI): one kill per rig on short plans.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))

from conftest import SMALL_XYTHETA, XY_NOISE_UM  # noqa: E402

VARS = ("time", "cmd_x", "cmd_y", "cmd_theta", "meas_x", "meas_y", "meas_theta", "pose", "cycle", "direction")
INDEX = ("cmd_x", "cmd_y", "cmd_theta", "pose", "cycle", "direction")


def _campaign(rig: str, workdir: Path, poses: int, emulator_options: dict | None) -> Path:
    c = yaml.safe_load(yaml.safe_dump(SMALL_XYTHETA))
    c["identification"]["poses"] = poses
    if rig == "simulated":
        c["rig"] = {"factory": "toyrigs:slow_simulated", "options": {"seconds": 0.004}}
    else:
        c["rig"] = {"factory": "gcs", "options": emulator_options}
    path = workdir / f"sigkill-{rig}.yaml"
    path.write_text(yaml.safe_dump(c))
    return path


def _start(campaign: Path, out: Path) -> subprocess.Popen:
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(ROOT / "tests"), os.environ.get("PYTHONPATH")])),
    }
    cmd = [
        sys.executable,
        "-m",
        "calflow",
        "acquire",
        "--campaign",
        str(campaign),
        "--plan",
        "identification",
        "--out",
        str(out),
        "--rig-plugins",
        "toyrigs",
    ]
    return subprocess.Popen(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)


def _journal(out: Path) -> list[dict]:
    from calflow.acquisition.checkpoint import Journal

    path = Path(f"{out}.journal")
    try:
        digest = json.loads(path.read_text().split("\n", 1)[0])["plan_digest"]
    except (OSError, ValueError, KeyError):
        return []
    return Journal(path, digest).load()


def _uninterrupted(campaign: Path):
    """The run ``calflow acquire`` would write, acquired in this process (no kill)."""
    import argparse

    from calflow.acquisition.runner import acquire
    from calflow.commands.common import meta, open_rig
    from calflow.configuration.campaign import load as load_campaign
    from calflow.family import family_of

    c = load_campaign(campaign, ["toyrigs"])
    job = family_of(c["robot"]).plan(c["robot"], "identification")(c, argparse.Namespace(model=None))
    rig, source = open_rig(c, job.run_id, job.plan.start_s, ["toyrigs"])
    try:
        return acquire(job.plan, rig, meta(c, source, "identification", job.model))
    finally:
        rig.close()


def _run_and_kill(
    campaign: Path, out: Path, had: int, rng: np.random.Generator, max_delay_s: float
) -> tuple[bool, int]:
    """Start an acquisition; SIGKILL it at a random time after it journaled a new sample.

    Returns (killed, journal length after)."""
    proc = _start(campaign, out)
    deadline = time.monotonic() + 120
    while proc.poll() is None and len(_journal(out)) <= had and time.monotonic() < deadline:
        time.sleep(0.01)
    if proc.poll() is None:
        time.sleep(rng.uniform(0.0, max_delay_s))
        proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    killed = proc.returncode == -signal.SIGKILL
    if not killed and proc.returncode != 0:
        raise RuntimeError(f"acquisition failed: {proc.stderr.read().decode()[-500:]}")
    return killed, len(_journal(out))


def kill_chain(
    rig: str,
    workdir: Path,
    *,
    kills: int,
    rng: np.random.Generator,
    poses: int = 400,
    max_delay_s: float = 0.15,
) -> dict:
    """``kills`` SIGKILLs of one acquisition on ``rig`` ("simulated" | "gcs"), resumed."""
    from calflow.data.io import open_dataset

    workdir.mkdir(parents=True, exist_ok=True)
    emu = None
    options = None
    if rig == "gcs":
        from calflow.xytheta.stage.emulate import emulated_rig_options

        emu, options = emulated_rig_options(SMALL_XYTHETA, time_scale=100.0, timeout=1.0)
        options["poll_s"] = 0.002
    try:
        campaign = _campaign(rig, workdir, poses, options)
        a = _uninterrupted(campaign)
        out = workdir / f"{rig}-killed.nc"
        seen: list[list[dict]] = []
        never_shrank, done, had, t0 = True, 0, 0, time.monotonic()
        while done < kills:
            killed, now = _run_and_kill(campaign, out, had, rng, max_delay_s)
            if not killed:
                break  # the run completed before the kill: the chain is over
            done += 1
            never_shrank &= now >= had
            had = now
            seen.append(_journal(out))
        if not out.exists():
            proc = _start(campaign, out)
            if proc.wait(timeout=600) != 0:
                raise RuntimeError(f"resumed run failed: {proc.stderr.read().decode()[-500:]}")
        wall = time.monotonic() - t0
    finally:
        if emu is not None:
            emu.stop()
    b = open_dataset(out)
    n_plan, n = a.sizes["sample"], b.sizes["sample"]
    lost = max(0, n_plan - n)
    for rows in seen:
        for i, row in enumerate(rows):
            if i >= n or any(
                not np.isclose(row[k], float(b[k].values[i]), rtol=0, atol=0, equal_nan=True)
                for k in VARS
                if k in row
            ):
                lost += 1
    m = min(n, n_plan)
    wrong = np.zeros(m, dtype=bool)
    for k in INDEX:
        wrong |= a[k].values[:m] != b[k].values[:m]
    dup = max(0, n - n_plan) + int(wrong.sum())
    if rig == "simulated":
        equal = n == n_plan and all(np.array_equal(a[k].values, b[k].values, equal_nan=True) for k in VARS)
    else:
        equal = (
            n == n_plan
            and all(np.array_equal(a[k].values, b[k].values) for k in INDEX)
            and bool(np.all(np.diff(b["time"].values) > 0))
            and all(
                np.nanmax(np.abs(a[k].values - b[k].values)) < 10 * XY_NOISE_UM for k in ("meas_x", "meas_y")
            )
        )
    return {
        "rig": rig,
        "kills": done,
        "samples": int(n_plan),
        "lost": int(lost),
        "duplicated": int(dup),
        "journal_never_shrank": bool(never_shrank),
        "equal_to_uninterrupted": bool(equal),
        "wall_s": round(wall, 1),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--kills", type=int, default=50, help="total SIGKILLs, split over the rigs")
    p.add_argument("--per-chain", type=int, default=10, help="kills per acquisition")
    p.add_argument("--seed", type=int, default=2024)
    p.add_argument("--workdir", type=Path, default=Path("/tmp/calflow-sigkill"))
    p.add_argument("--json", action="store_true", help="print the figures as JSON")
    p.add_argument(
        "--smoke", action="store_true", help="CI: one SIGKILL per rig, on short plans (60 and 40 poses)"
    )
    a = p.parse_args(argv)
    poses = {"simulated": 1000, "gcs": 400}
    if a.smoke:
        a.kills, a.per_chain, poses = 2, 1, {"simulated": 60, "gcs": 40}
    rng = np.random.default_rng(a.seed)
    chains, total, k = [], 0, 0
    while total < a.kills and k < 4 * a.kills:  # chains whose run ends before its kill count none
        rig = ("simulated", "gcs")[k % 2]
        want = min(a.per_chain, a.kills - total)
        r = kill_chain(rig, a.workdir / f"chain{k}", kills=want, rng=rng, poses=poses[rig])
        chains.append(r)
        total += r["kills"]
        k += 1
        if not a.json:
            print(r, flush=True)
    summary = {
        rig: {key: sum(c[key] for c in chains if c["rig"] == rig) for key in ("kills", "lost", "duplicated")}
        for rig in ("simulated", "gcs")
    }
    figures = {
        "kills": total,
        "lost": sum(c["lost"] for c in chains),
        "duplicated": sum(c["duplicated"] for c in chains),
        "all_equal_to_uninterrupted": all(c["equal_to_uninterrupted"] for c in chains),
        "journal_never_shrank": all(c["journal_never_shrank"] for c in chains),
        "per_rig": summary,
        "chains": chains,
    }
    print(
        json.dumps(figures, indent=1)
        if a.json
        else f"{total} SIGKILLs: lost {figures['lost']}, duplicated {figures['duplicated']}, "
        f"all equal to the uninterrupted runs: {figures['all_equal_to_uninterrupted']}"
    )
    return 0 if figures["lost"] == figures["duplicated"] == 0 and figures["all_equal_to_uninterrupted"] else 1


if __name__ == "__main__":
    raise SystemExit(main())
