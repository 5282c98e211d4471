"""The instrument bench of a simulated XYΘ campaign that reads through images (``calflow
instrument-bench``): its camera and decoder on rendered frames, for the report's
measurement-system section (:mod:`calflow.instruments.bench`)."""

from __future__ import annotations

import numpy as np

from calflow.xytheta.stage.images import ImageSensor


def instrument_of(campaign: dict):
    """(pattern, camera) of a simulated campaign that reads through images."""
    from calflow.errors import ConfigError
    from calflow.xytheta.stage.physics import check_options, truth_from_options

    options = dict(campaign["rig"].get("options") or {})
    sensor = check_options(**options).get("sensor") or {}
    if campaign["rig"]["factory"] != "simulated" or sensor.get("sensor") != "images":
        raise ConfigError(
            f"{campaign['name']}: key 'rig.options.sensor': the instrument bench needs the simulated rig "
            "reading through images (sensor: images)"
        )
    return ImageSensor(
        truth_from_options(options), sensor, seed=int(campaign.get("seed") or 0), stream="bench"
    )


def bench_command(args) -> None:
    """``calflow instrument-bench``: the camera and decoder of the campaign's images rig on
    rendered frames around the middle of the pattern (:mod:`calflow.instruments.bench`)."""
    from calflow.commands.common import campaign_of, meta
    from calflow.data.io import output_folder, write_dataset, write_json
    from calflow.instruments.bench import bench

    c = campaign_of(args)
    sensor = instrument_of(c)
    rx, ry = sensor.pattern.range_um
    theta = float(np.mean(c["identification"]["theta_deg"]))
    output_folder(args.out)
    ds, throughput = bench(
        sensor.pattern, sensor.camera, (0.5 * rx, 0.5 * ry, theta), seed=int(c.get("seed") or 0)
    )
    ds.attrs = {**meta(c, "simulated", "instrument").attrs("metrics"), **ds.attrs}
    if getattr(args, "throughput", None):
        write_json(throughput, args.throughput)
    write_dataset(ds, args.out)
