"""`calflow import-csv`: a CSV and a column mapping become a run dataset."""

import numpy as np
import pytest
import yaml

from calflow.data.io import open_dataset, write_dataset
from calflow.data.runs import RunMetadata
from calflow.data.validate import validate_dataset
from calflow.errors import DataError
from calflow.data.importing import check_mapping, import_csv, load_mapping

META = RunMetadata(campaign="bench", robot="xytheta", source="replay", plan="identification",
                   config_sha256="0" * 64, start="2026-03-02T10:00:00+00:00")

MAPPING = {
    "robot": "xytheta",
    "plan": "identification",
    "dwell_s": 1.0,
    "columns": {
        "time": {"column": "t_s"},
        "cmd_x": {"column": "X_cmd_mm", "scale": 1000},
        "cmd_y": {"column": "Y_cmd_mm", "scale": 1000},
        "cmd_theta": {"column": "theta_cmd_deg"},
        "meas_x": {"column": "x_vision_mm", "scale": 1000},
        "meas_y": {"column": "y_vision_um"},
        "meas_theta": {"column": "theta_vision_deg"},
        "temperature": {"columns": {"T1": "temp1", "T2": "temp2"}},
        "pose": {"column": "pose"},
    },
}

# Shuffled column order, mm units, an unused column, a lost vision reading (empty cell).
HEADER = "temp2,theta_vision_deg,pose,X_cmd_mm,comment,y_vision_um,t_s,x_vision_mm,Y_cmd_mm,theta_cmd_deg,temp1"
ROWS = [
    "21.02,0.0001,0,0,home,1502.85,0.0,1.00249,0,0,21.01",
    "21.03,1.2501,1,1.5,,1576.46,2.5,1.44418,0.75,1.25,21.00",
    "21.03,3.0002,2,3.25,,,5.0,,1.2,3.0,20.99",
    "21.04,4.9999,3,0.4,last,1011.96,7.5,3.18926,1.999,5.0,21.02",
]


def write(tmp_path, header=HEADER, rows=ROWS, name="bench.csv", delimiter=","):
    path = tmp_path / name
    lines = [header, *rows] if header is not None else rows
    path.write_text("\n".join(line.replace(",", delimiter) for line in lines) + "\n")
    return path


def test_import_converts_units_and_validates(tmp_path):
    ds = import_csv(write(tmp_path), MAPPING, META)
    assert validate_dataset(ds) == []
    assert ds.sizes == {"sample": 4, "sensor": 2}
    assert np.allclose(ds["cmd_x"].values, [0, 1500, 3250, 400])
    assert np.allclose(ds["cmd_y"].values, [0, 750, 1200, 1999])
    assert np.allclose(ds["meas_x"].values, [1002.49, 1444.18, np.nan, 3189.26], equal_nan=True)
    assert np.isnan(ds["meas_y"].values[2]) and np.isnan(ds["meas_x"].values[2])
    assert list(ds["sensor"].values) == ["T1", "T2"]
    assert np.allclose(ds["temperature"].sel(sensor="T2").values, [21.02, 21.03, 21.03, 21.04])
    assert list(ds["pose"].values) == [0, 1, 2, 3] and list(ds["cycle"].values) == [0] * 4
    assert list(ds["direction"].values) == [0] * 4
    assert ds["cmd_x"].attrs["units"] == "um" and ds["cmd_theta"].attrs["units"] == "degree"
    assert ds["temperature"].attrs["units"] == "degC"
    assert ds["time"].attrs["units"] == "seconds since 2026-03-02T10:00:00+00:00"
    assert ds.attrs["plan"] == "identification" and ds.attrs["source"] == "replay"
    assert ds.attrs["dwell_s"] == 1.0 and ds.attrs["imported_from"] == "bench.csv"
    again = open_dataset(write_dataset(ds, tmp_path / "run.nc"), kind="run")
    assert validate_dataset(again) == []


def test_mapping_file_iso_time_delimiter_and_defaults(tmp_path):
    mapping = yaml.safe_load(yaml.safe_dump(MAPPING))
    mapping["columns"]["time"] = {"column": "stamp", "format": "iso"}
    del mapping["columns"]["pose"], mapping["dwell_s"]
    mapping["columns"]["direction"] = {"column": "dir"}
    mapping["delimiter"] = ";"
    mfile = tmp_path / "m.yaml"
    mfile.write_text(yaml.safe_dump(mapping))
    header = HEADER.replace("t_s", "stamp").replace("pose", "dir")
    stamps = ["2026-03-02T10:00:00", "2026-03-02T10:00:02.5", "2026-03-02T11:00:02.5+01:00", "2026-03-02T10:01:00Z"]
    rows = []
    for row, stamp, d in zip(ROWS, stamps, ["0", "1", "-1", "1"]):
        cells = row.split(",")
        cells[6], cells[2] = stamp, d
        rows.append(",".join(cells))
    ds = import_csv(write(tmp_path, header, rows, delimiter=";"), load_mapping(mfile), META)
    assert np.allclose(ds["time"].values, [0.0, 2.5, 2.5, 60.0])
    assert list(ds["pose"].values) == [0, 1, 2, 3] and list(ds["direction"].values) == [0, 1, -1, 1]
    assert "dwell_s" not in ds.attrs
    assert validate_dataset(ds) == []


def expect(match, fn, *args):
    with pytest.raises(DataError) as err:
        fn(*args)
    msg = str(err.value)
    assert "\n" not in msg, msg
    assert match in msg, msg
    return msg


def swap(cell_row, col, value, rows=ROWS):
    cols = HEADER.split(",")
    out = list(rows)
    cells = out[cell_row].split(",")
    cells[cols.index(col)] = value
    out[cell_row] = ",".join(cells)
    return out


@pytest.mark.parametrize("header,rows,message", [
    (HEADER.replace("Y_cmd_mm", "Ycmd"), ROWS,
     "bench.csv: row 1: column 'Y_cmd_mm' (for cmd_y) missing from the header"),
    (HEADER, swap(2, "X_cmd_mm", "3,25"), None),  # field count: '3,25' splits a cell
    (HEADER, swap(2, "t_s", "abc"), "bench.csv: row 4, column 't_s' (time): expected a number, got 'abc'"),
    (HEADER, swap(3, "Y_cmd_mm", ""), "bench.csv: row 5, column 'Y_cmd_mm' (cmd_y): expected a number, got ''"),
    (HEADER, swap(1, "temp1", "warm"),
     "bench.csv: row 3, column 'temp1' (temperature T1): expected a number, got 'warm'"),
    (HEADER, swap(3, "t_s", "4.0"),
     "bench.csv: row 5, column 't_s' (time): expected non-decreasing time, got 4.0 s after 5.0 s"),
    (HEADER, swap(2, "pose", "2.5"), "bench.csv: row 4, column 'pose' (pose): expected an integer, got '2.5'"),
    (HEADER, swap(1, "x_vision_mm", "inf"),
     "bench.csv: row 3, column 'x_vision_mm' (meas_x): expected a finite number, got 'inf'"),
    (HEADER + ",t_s", [r + ",0" for r in ROWS], "bench.csv: row 1: column 't_s' appears twice in the header"),
    (HEADER, [], "bench.csv: row 2: expected a data row after the header, the file has none"),
    (None, [], "bench.csv: row 1: expected a header row, the file is empty"),
    (HEADER, ROWS[:2] + ["21.0,0.1,9"] + ROWS[3:],
     "bench.csv: row 4: expected 11 fields as in the header, got 3 (check the delimiter)"),
])
def test_malformed_csv_yields_one_precise_line(tmp_path, header, rows, message):
    msg = expect("bench.csv: row", import_csv, write(tmp_path, header, rows), MAPPING, META)
    if message is None:
        assert "row 4: expected 11 fields as in the header, got 12" in msg
    else:
        assert message in msg


def test_direction_values_are_checked(tmp_path):
    mapping = {**MAPPING, "columns": {**MAPPING["columns"], "direction": {"column": "pose"}}}
    expect("bench.csv: row 4, column 'pose' (direction): expected one of [-1, 0, 1], got '2'",
           import_csv, write(tmp_path), mapping, META)


def test_metadata_must_agree_with_the_mapping(tmp_path):
    path = write(tmp_path)
    expect("mapping plan 'identification' differs from the run metadata plan 'validation'",
           import_csv, path, MAPPING, RunMetadata("bench", "xytheta", "replay", "validation", "0" * 64))
    expect("mapping robot 'xytheta' differs from the campaign robot 'stage1d'",
           import_csv, path, MAPPING, RunMetadata("bench", "stage1d", "replay", "identification", "0" * 64))
    expect("gone.csv: file not found", import_csv, tmp_path / "gone.csv", MAPPING, META)


def mapping_file(tmp_path, body):
    path = tmp_path / "map.yaml"
    path.write_text(body if isinstance(body, str) else yaml.safe_dump(body))
    return path


def with_columns(**changes):
    cols = {k: v for k, v in {**MAPPING["columns"], **changes}.items() if v is not None}
    return {**MAPPING, "columns": cols}


@pytest.mark.parametrize("body,message", [
    ({**MAPPING, "colums": {}}, "map.yaml: key 'colums': unknown; expected some of"),
    (with_columns(cmd_q={"column": "q"}), "map.yaml: key 'columns.cmd_q': unknown run variable; expected one of"),
    (with_columns(cmd_z={"column": "z"}), "map.yaml: key 'columns.cmd_z': unknown run variable"),
    (with_columns(cmd_x={"column": "X", "scal": 1000}), "map.yaml: key 'columns.cmd_x.scal': unknown"),
    (with_columns(cmd_x={"column": "X", "scale": "1000x"}),
     "map.yaml: key 'columns.cmd_x.scale': expected a finite number, got '1000x'"),
    (with_columns(cmd_x={"col": "X"}), "map.yaml: key 'columns.cmd_x.col': unknown"),
    (with_columns(cmd_x={"scale": 2}), "map.yaml: key 'columns.cmd_x.column': expected the name of one CSV column"),
    (with_columns(meas_y=None), "map.yaml: key 'columns.meas_y': missing; a xytheta run needs it"),
    (with_columns(time=None), "map.yaml: key 'columns.time': missing"),
    (with_columns(meas_x={"column": "x", "format": "iso"}), "map.yaml: key 'columns.meas_x.format': expected"),
    (with_columns(temperature={"column": "t1"}), "map.yaml: key 'columns.temperature.columns': expected a mapping"),
    (with_columns(pose={"column": "p", "offset": 1}), "map.yaml: key 'columns.pose': scale/offset do not apply"),
    ({**MAPPING, "robot": "hexapod"}, "map.yaml: key 'robot': expected one of"),
    ({**MAPPING, "plan": ""}, "map.yaml: key 'plan': expected a plan name"),
    ({**MAPPING, "delimiter": ";;"}, "map.yaml: key 'delimiter': expected one character"),
    ("- just\n- a list\n", "map.yaml: expected a mapping with keys"),
    ("columns: {time: [unclosed\n", "map.yaml: line"),
])
def test_bad_mapping_files_are_named(tmp_path, body, message):
    expect(message, load_mapping, mapping_file(tmp_path, body))


def test_check_mapping_normalises_and_is_idempotent():
    m = check_mapping(MAPPING)
    assert m["columns"]["cmd_x"] == {"column": "X_cmd_mm", "scale": 1000.0, "offset": 0.0, "format": "number"}
    assert check_mapping(m) == m
