"""`calflow import-csv`: a CSV and a column mapping become a run dataset."""

import numpy as np
import pytest
import yaml

from calflow.data.importing import check_mapping, import_csv, load_mapping
from calflow.data.io import open_dataset, write_dataset
from calflow.data.runs import RunMetadata
from calflow.data.validate import validate_dataset
from calflow.errors import DataError

META = RunMetadata(
    campaign="bench",
    robot="xytheta",
    source="replay",
    plan="identification",
    config_sha256="0" * 64,
    start="2026-03-02T10:00:00+00:00",
)

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
HEADER = (
    "temp2,theta_vision_deg,pose,X_cmd_mm,comment,y_vision_um,t_s,x_vision_mm,Y_cmd_mm,theta_cmd_deg,temp1"
)
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
    stamps = [
        "2026-03-02T10:00:00",
        "2026-03-02T10:00:02.5",
        "2026-03-02T11:00:02.5+01:00",
        "2026-03-02T10:01:00Z",
    ]
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


@pytest.mark.parametrize(
    "header,rows,message",
    [
        (
            HEADER.replace("Y_cmd_mm", "Ycmd"),
            ROWS,
            "bench.csv: row 1: column 'Y_cmd_mm' (for cmd_y) missing from the header",
        ),
        (HEADER, swap(2, "X_cmd_mm", "3,25"), None),  # field count: '3,25' splits a cell
        (
            HEADER,
            swap(2, "t_s", "abc"),
            "bench.csv: row 4, column 't_s' (time): expected a number, got 'abc'",
        ),
        (
            HEADER,
            swap(3, "Y_cmd_mm", ""),
            "bench.csv: row 5, column 'Y_cmd_mm' (cmd_y): expected a number, got ''",
        ),
        (
            HEADER,
            swap(1, "temp1", "warm"),
            "bench.csv: row 3, column 'temp1' (temperature T1): expected a number, got 'warm'",
        ),
        (
            HEADER,
            swap(3, "t_s", "4.0"),
            "bench.csv: row 5, column 't_s' (time): expected non-decreasing time, got 4.0 s after 5.0 s",
        ),
        (
            HEADER,
            swap(2, "pose", "2.5"),
            "bench.csv: row 4, column 'pose' (pose): expected an integer, got '2.5'",
        ),
        (
            HEADER,
            swap(1, "x_vision_mm", "inf"),
            "bench.csv: row 3, column 'x_vision_mm' (meas_x): expected a finite number, got 'inf'",
        ),
        (
            HEADER + ",t_s",
            [r + ",0" for r in ROWS],
            "bench.csv: row 1: column 't_s' appears twice in the header",
        ),
        (HEADER, [], "bench.csv: row 2: expected a data row after the header, the file has none"),
        (None, [], "bench.csv: row 1: expected a header row, the file is empty"),
        (
            HEADER,
            ROWS[:2] + ["21.0,0.1,9"] + ROWS[3:],
            "bench.csv: row 4: expected 11 fields as in the header, got 3 (check the delimiter)",
        ),
    ],
)
def test_malformed_csv_yields_one_precise_line(tmp_path, header, rows, message):
    msg = expect("bench.csv: row", import_csv, write(tmp_path, header, rows), MAPPING, META)
    if message is None:
        assert "row 4: expected 11 fields as in the header, got 12" in msg
    else:
        assert message in msg


def test_direction_values_are_checked(tmp_path):
    mapping = {**MAPPING, "columns": {**MAPPING["columns"], "direction": {"column": "pose"}}}
    expect(
        "bench.csv: row 4, column 'pose' (direction): expected one of [-1, 0, 1], got '2'",
        import_csv,
        write(tmp_path),
        mapping,
        META,
    )


def test_metadata_must_agree_with_the_mapping(tmp_path):
    path = write(tmp_path)
    expect(
        "mapping plan 'identification' differs from the run metadata plan 'validation'",
        import_csv,
        path,
        MAPPING,
        RunMetadata("bench", "xytheta", "replay", "validation", "0" * 64),
    )
    expect(
        "mapping robot 'xytheta' differs from the campaign robot 'stage1d'",
        import_csv,
        path,
        MAPPING,
        RunMetadata("bench", "stage1d", "replay", "identification", "0" * 64),
    )
    expect("gone.csv: file not found", import_csv, tmp_path / "gone.csv", MAPPING, META)


def mapping_file(tmp_path, body):
    path = tmp_path / "map.yaml"
    path.write_text(body if isinstance(body, str) else yaml.safe_dump(body))
    return path


def with_columns(**changes):
    cols = {k: v for k, v in {**MAPPING["columns"], **changes}.items() if v is not None}
    return {**MAPPING, "columns": cols}


@pytest.mark.parametrize(
    "body,message",
    [
        ({**MAPPING, "colums": {}}, "map.yaml: key 'colums': unknown; expected some of"),
        (
            with_columns(cmd_q={"column": "q"}),
            "map.yaml: key 'columns.cmd_q': unknown run variable; expected one of",
        ),
        (with_columns(cmd_z={"column": "z"}), "map.yaml: key 'columns.cmd_z': unknown run variable"),
        (with_columns(cmd_x={"column": "X", "scal": 1000}), "map.yaml: key 'columns.cmd_x.scal': unknown"),
        (
            with_columns(cmd_x={"column": "X", "scale": "1000x"}),
            "map.yaml: key 'columns.cmd_x.scale': expected a finite number, got '1000x'",
        ),
        (with_columns(cmd_x={"col": "X"}), "map.yaml: key 'columns.cmd_x.col': unknown"),
        (
            with_columns(cmd_x={"scale": 2}),
            "map.yaml: key 'columns.cmd_x.column': expected the name of one CSV column",
        ),
        (with_columns(meas_y=None), "map.yaml: key 'columns.meas_y': missing; a xytheta run needs it"),
        (with_columns(time=None), "map.yaml: key 'columns.time': missing"),
        (
            with_columns(meas_x={"column": "x", "format": "iso"}),
            "map.yaml: key 'columns.meas_x.format': expected",
        ),
        (
            with_columns(temperature={"column": "t1"}),
            "map.yaml: key 'columns.temperature.columns': expected a mapping",
        ),
        (
            with_columns(pose={"column": "p", "offset": 1}),
            "map.yaml: key 'columns.pose': scale/offset do not apply",
        ),
        ({**MAPPING, "robot": "tripod"}, "map.yaml: key 'robot': expected one of"),
        ({**MAPPING, "plan": ""}, "map.yaml: key 'plan': expected a plan name"),
        ({**MAPPING, "delimiter": ";;"}, "map.yaml: key 'delimiter': expected one character"),
        ("- just\n- a list\n", "map.yaml: expected a mapping with keys"),
        ("columns: {time: [unclosed\n", "map.yaml: line"),
    ],
)
def test_bad_mapping_files_are_named(tmp_path, body, message):
    expect(message, load_mapping, mapping_file(tmp_path, body))


def test_check_mapping_normalises_and_is_idempotent():
    m = check_mapping(MAPPING)
    assert m["columns"]["cmd_x"] == {"column": "X_cmd_mm", "scale": 1000.0, "offset": 0.0, "format": "number"}
    assert check_mapping(m) == m


def test_a_duplicated_row_is_refused_naming_both_rows(tmp_path):
    rows = ROWS[:3] + [ROWS[2]] + ROWS[3:]
    msg = expect(
        "bench.csv: row 5: repeats row 4 cell for cell",
        import_csv,
        write(tmp_path, HEADER, rows),
        MAPPING,
        META,
    )
    assert "count one measurement twice" in msg
    assert not list(tmp_path.glob("*.nc"))


# ---------------------------------------------------------------- ecmc ISO 230-2 (.dat) files

from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st

from calflow.data import ecmc_iso230, laser_tracker  # noqa: E402
from calflow.data.recordings import iso230_run, tracker_run  # noqa: E402
from calflow.data.recordings import load as load_recording
from calflow.metrics import iso230_2  # noqa: E402
from calflow.metrics.iso230_2_runs import iso230_2_of_run  # noqa: E402

DATA = __import__("pathlib").Path(__file__).parents[1] / "data" / "recordings"

ISO_TEXT = """# axis 1, by hand
UNIT=mm
CYCLES=2
POSITIONS=3
DEC=5
TGT_DATA[1]=10
TGT_DATA[2]=20
REF_DATA_FWD[1,1]=10.001
TGT_DATA[3]=30
REF_DATA_FWD[2,1]=20.002
REF_DATA_FWD[3,1]=29.999
REF_DATA_FWD[1,2]=10.0015
REF_DATA_FWD[2,2]=20.0025
REF_DATA_FWD[3,2]=29.9985
REF_DATA_BWD[1,1]=10.003
REF_DATA_BWD[2,1]=20.004 
REF_DATA_BWD[3,1]=30.001
REF_DATA_BWD[1,2]=10.0035
REF_DATA_BWD[2,2]=20.0045
REF_DATA_BWD[3,2]=30.0005
"""


def test_ecmc_file_parses_by_hand():
    rec = ecmc_iso230.parse(ISO_TEXT, "a_ISO230.dat")
    assert rec.unit == "mm" and rec.scale_um == 1000.0
    assert rec.targets.tolist() == [10, 20, 30]
    assert rec.forward.tolist() == [[10.001, 10.0015], [20.002, 20.0025], [29.999, 29.9985]]
    assert rec.backward[:, 1].tolist() == [10.0035, 20.0045, 30.0005]


def test_standard_cycle_rows_and_iso230_2_of_the_run_match_the_file():
    rec = ecmc_iso230.read(DATA / "axis1_ISO230.dat")
    rows = ecmc_iso230.standard_cycle(rec)
    p, c = rec.forward.shape
    assert len(rows["target"]) == 2 * p * c
    # cycle 1: forward 1..P then backward P..1; the reading of backward approach to position P-1 of cycle 2
    assert rows["target"][p] == rec.targets[-1] * 1000 and rows["direction"][p] == -1
    assert rows["reading"][2 * p + p + 1] == rec.backward[p - 2, 1] * 1000
    ds, plan = iso230_run(DATA / "axis1_ISO230.dat", "metrology")
    assert validate_dataset(ds) == [] and ds.attrs["robot"] == "stage1d" and len(plan) == 2 * p * c
    got = iso230_2_of_run(ds)
    want = iso230_2(rec.targets * 1000, rec.forward * 1000, rec.backward * 1000)
    for key in ("E", "M", "B", "R", "A", "R_fwd", "B_mean"):
        assert got[f"{key}_nm"] == pytest.approx(float(getattr(want, key)) * 1000, rel=1e-9, abs=1e-9), key


@pytest.mark.parametrize(
    "change,message",
    [
        (("UNIT=mm", "UNIT=deg"), "line 2: UNIT: expected a length unit"),
        (("CYCLES=2", "CYCLES=two"), "line 3: CYCLES: expected a whole number >= 1, got 'two'"),
        (("CYCLES=2", "CYCLES=0"), "line 3: CYCLES: expected a whole number from 1 to 100000"),
        (("TGT_DATA[2]=20", "TGT_DATA[2]=abc"), "line 7: TGT_DATA[2]: expected a number, got 'abc'"),
        (("TGT_DATA[2]=20", "TGT_DATA[2]=nan"), "line 7: TGT_DATA[2]: expected a finite number"),
        (
            ("TGT_DATA[2]=20", "TGT_DATA[2]=35"),
            "TGT_DATA[3]: expected targets strictly increasing or decreasing",
        ),
        (
            ("REF_DATA_FWD[2,1]", "REF_DATA_FWD[2]"),
            "line 10: REF_DATA_FWD: expected 1-based indices REF_DATA_FWD[i,j]",
        ),
        (("REF_DATA_FWD[2,1]", "REF_DATA_FWD[0,1]"), "line 10: REF_DATA_FWD: expected 1-based indices"),
        (
            ("REF_DATA_FWD[2,1]", "REF_DATA_FWD[2,3]"),
            "line 10: REF_DATA_FWD[2,3]: index 3 is beyond CYCLES=2",
        ),
        (
            ("REF_DATA_FWD[2,1]", "REF_DATA_FWD[1,1]"),
            "line 10: REF_DATA_FWD[1,1] given again (first on line 8)",
        ),
        (
            ("REF_DATA_BWD[3,2]=30.0005", ""),
            "REF_DATA_BWD[3,2] missing; expected POSITIONS=3 x CYCLES=2 readings",
        ),
        (("POSITIONS=3", "POSITIONS=100000"), "TGT_DATA[4] missing; expected POSITIONS=100000 targets"),
        (("DEC=5", "CYCELS=5"), "line 5: unknown key 'CYCELS'"),
        (("DEC=5", "just words"), "line 5: expected '# comment' or KEY=value, got 'just words'"),
        (("UNIT=mm", "UNIT=mm\nUNIT=um"), "line 3: UNIT given again (first on line 2)"),
    ],
)
def test_bad_ecmc_files_give_one_line_naming_file_and_line(tmp_path, change, message):
    path = tmp_path / "bad_ISO230.dat"
    path.write_text(ISO_TEXT.replace(*change, 1))
    msg = expect(message, ecmc_iso230.read, path)
    assert msg.startswith(f"{path}: ")


def test_unreadable_ecmc_files(tmp_path):
    expect("gone_ISO230.dat: file not found", ecmc_iso230.read, tmp_path / "gone_ISO230.dat")
    (tmp_path / "bin_ISO230.dat").write_bytes(b"UNIT=mm\n\xff\xfe")
    expect("bin_ISO230.dat: not UTF-8 text", ecmc_iso230.read, tmp_path / "bin_ISO230.dat")


finite = st.floats(-1e6, 1e6, allow_nan=False, allow_infinity=False)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(
    p=st.integers(1, 5),
    c=st.integers(1, 4),
    unit=st.sampled_from(sorted(ecmc_iso230.UM_PER_UNIT)),
    start=finite,
    step=st.floats(1e-3, 1e3),
    data=st.data(),
)
def test_ecmc_writer_and_parser_round_trip(tmp_path, p, c, unit, start, step, data):
    targets = start + step * np.arange(p)
    fwd = np.array(data.draw(st.lists(finite, min_size=p * c, max_size=p * c))).reshape(p, c)
    bwd = np.array(data.draw(st.lists(finite, min_size=p * c, max_size=p * c))).reshape(p, c)
    rec = ecmc_iso230.Iso230Recording(unit, targets, fwd, bwd)
    back = ecmc_iso230.read(ecmc_iso230.write(rec, tmp_path / "rt_ISO230.dat", ("round trip",)))
    assert back.unit == unit
    assert np.array_equal(back.targets, targets) and np.array_equal(back.forward, fwd)
    assert np.array_equal(back.backward, bwd)


@settings(max_examples=120, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.integers(0, 21), st.sampled_from(["drop", "dup", "swap", "text", "cut"]), st.text(max_size=12)
        ),
        max_size=4,
    )
)
def test_ecmc_parser_fuzz_never_gives_a_traceback(edits):
    """Mutated files (lines dropped, repeated, swapped, garbled, cut) parse or give calflow's one line."""
    lines = ISO_TEXT.splitlines()
    for k, op, junk in edits:
        k %= max(len(lines), 1)
        if not lines:
            break
        if op == "drop":
            del lines[k]
        elif op == "dup":
            lines.insert(k, lines[k])
        elif op == "swap":
            lines[k], lines[-1] = lines[-1], lines[k]
        elif op == "text":
            lines[k] = lines[k][: len(lines[k]) // 2] + junk
        else:
            lines[k] = lines[k][: len(junk)]
    try:
        rec = ecmc_iso230.parse("\n".join(lines), "fuzz_ISO230.dat")
    except DataError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("fuzz_ISO230.dat: ")
    else:
        assert rec.forward.shape == rec.backward.shape == (len(rec.targets), rec.forward.shape[1])
        assert np.all(np.isfinite(rec.forward)) and np.all(np.isfinite(rec.backward))


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=300))
def test_ecmc_parser_fuzz_on_any_text(text):
    try:
        ecmc_iso230.parse(text, "any.dat")
    except DataError as exc:
        assert "\n" not in str(exc) and str(exc).startswith("any.dat: ")


# ---------------------------------------------------------------- laser-tracker exports (CSV)


def test_tracker_fixture_reads_in_mm_and_becomes_a_stage2d_run():
    rec = laser_tracker.read(DATA / "stage2d_tracker.csv")
    assert rec.start == "2026-03-02T10:00:00+00:00" and rec.time[0] == 0.0 and rec.time[1] == 10.0
    assert rec.command.shape == rec.measured.shape == (36, 3)
    assert sorted(set(rec.pose.tolist())) == list(range(9)) and rec.cycle.max() == 3
    ds, plan = tracker_run(DATA / "stage2d_tracker.csv", "training")
    assert validate_dataset(ds) == [] and ds.attrs["robot"] == "stage2d"
    assert np.allclose(ds["cmd_x"].values, rec.command[:, 0] * 1000)
    assert np.allclose(ds["meas_y"].values, rec.measured[:, 1] * 1000)
    z = rec.measured[:, 2] * 1000
    assert ds.attrs["z_range_um"] == pytest.approx(z.max() - z.min())
    assert list(plan.commands) == ["x", "y"] and len(plan) == 36


def test_tracker_round_trip_and_default_cycles(tmp_path):
    rec = laser_tracker.read(DATA / "stage2d_tracker.csv")
    lost = rec.measured.copy()
    lost[3, 1] = np.nan  # a lost reading survives as an empty cell
    rec = laser_tracker.TrackerRecording(rec.start, rec.time, rec.pose, rec.cycle, rec.command, lost)
    back = laser_tracker.read(laser_tracker.write(rec, tmp_path / "t.csv"))
    assert np.array_equal(back.measured, lost, equal_nan=True) and np.array_equal(back.cycle, rec.cycle)
    text = (tmp_path / "t.csv").read_text().replace(",cycle\n", "\n", 1)
    (tmp_path / "nocycle.csv").write_text(
        "\n".join(line.rsplit(",", 1)[0] if k else line for k, line in enumerate(text.splitlines())) + "\n"
    )
    assert np.array_equal(laser_tracker.read(tmp_path / "nocycle.csv").cycle, rec.cycle)


TRACKER = [
    "timestamp,pose,X_cmd_mm,Y_cmd_mm,Z_cmd_mm,X_mm,Y_mm,Z_mm",
    "2026-03-02T10:00:00Z,0,0,0,5,0.001,0.002,5.001",
    "2026-03-02T10:00:10Z,1,1,0,5,1.001,0.002,5.001",
    "2026-03-02T10:00:20Z,0,0,0,5,0.0012,0.0021,5.0009",
]


@pytest.mark.parametrize(
    "row,cells,message",
    [
        (3, None, "t.csv: row 4: repeats row 3 cell for cell"),
        (2, {0: "10:00"}, "t.csv: row 2, column 'timestamp': expected an ISO 8601 timestamp"),
        (
            2,
            {0: "2026-03-02T10:00:00"},
            "t.csv: row 2, column 'timestamp': expected a timestamp with its time zone",
        ),
        (3, {0: "2026-03-02T09:00:00Z"}, "t.csv: row 3, column 'timestamp': expected a time not before"),
        (3, {1: "-1"}, "t.csv: row 3, column 'pose': expected an integer >= 0, got '-1'"),
        (3, {2: "1mm"}, "t.csv: row 3, column 'X_cmd_mm': expected a number (mm), got '1mm'"),
        (3, {2: ""}, "t.csv: row 3, column 'X_cmd_mm': expected a number (mm), got ''"),
        (3, {6: "inf"}, "t.csv: row 3, column 'Y_mm': expected a finite number (mm), got 'inf'"),
        (3, {4: "6"}, "t.csv: row 3, column 'Z_cmd_mm': expected the commanded Z of every row (5.0 mm)"),
        (3, {7: "5.0,1"}, "t.csv: row 3: expected 8 fields as in the header, got 9"),
    ],
)
def test_bad_tracker_exports_give_one_line(tmp_path, row, cells, message):
    lines = list(TRACKER)
    if cells is None:
        lines.insert(row, lines[row - 1])
    else:
        parts = lines[row - 1].split(",")
        for k, v in cells.items():
            parts[k] = v
        lines[row - 1] = ",".join(parts)
    (tmp_path / "t.csv").write_text("\n".join(lines) + "\n")
    expect(message, laser_tracker.read, tmp_path / "t.csv")


def test_tracker_header_problems(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("# only a comment\n")
    expect("t.csv: row 1: expected a header row", laser_tracker.read, path)
    path.write_text("# exported\n" + TRACKER[0].replace("Z_mm", "Zmm") + "\n")
    expect("t.csv: row 2: column 'Z_mm' missing from the header", laser_tracker.read, path)
    path.write_text(TRACKER[0] + "\n")
    expect("t.csv: row 2: expected a data row after the header", laser_tracker.read, path)


@pytest.mark.parametrize(
    "spec,message",
    [
        ("run.txt", "recordings.metrology: expected a .nc run file, an *ISO230.dat file or"),
        ({"file": "a.dat", "format": "ecmc"}, "recordings.metrology.format: expected one of"),
        (
            {"file": "a.csv", "format": "csv"},
            "recordings.metrology.mapping: expected the column mapping file",
        ),
        (
            {"file": "a.dat", "format": "ecmc_iso230", "mapping": "m.yaml"},
            "mapping: expected no mapping: it applies to format 'csv' only",
        ),
        ({"file": "a.dat", "fmt": "ecmc_iso230"}, "recordings.metrology.fmt: expected no such key"),
        ({"file": "nowhere_ISO230.dat", "format": "ecmc_iso230"}, "nowhere_ISO230.dat: file not found"),
    ],
)
def test_bad_recording_entries_are_named(spec, message):
    expect(message, load_recording, spec, "metrology")


def test_a_mapped_csv_recording_carries_its_plan(tmp_path):
    mfile = tmp_path / "m.yaml"
    mfile.write_text(yaml.safe_dump(MAPPING))
    path, ds, plan = load_recording(
        {"file": str(write(tmp_path)), "format": "csv", "mapping": str(mfile)}, "identification"
    )
    assert validate_dataset(ds) == [] and plan.name == "identification"
    assert np.allclose(plan.commands["x"], [0, 1500, 3250, 400]) and list(plan.pose) == [0, 1, 2, 3]


def test_import_recording_cli_writes_a_valid_run_or_one_line(tmp_path, monkeypatch, capsys):
    from calflow.cli import main

    root = DATA.parents[2]
    monkeypatch.chdir(root)  # the shipped campaigns name their recordings from the project folder
    out = tmp_path / "metrology.nc"
    assert (
        main(
            [
                "import-recording",
                str(DATA / "axis1_ISO230.dat"),
                "--format",
                "ecmc_iso230",
                "--plan",
                "metrology",
                "--campaign",
                "config/campaigns/recorded-iso230.yaml",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    ds = open_dataset(out, kind="run")
    assert validate_dataset(ds) == [] and ds.attrs["campaign"] == "recorded-iso230"
    assert ds.attrs["imported_from"] == "axis1_ISO230.dat" and ds.sizes["sample"] == 60
    out = tmp_path / "training.nc"
    assert (
        main(
            [
                "import-recording",
                str(DATA / "stage2d_tracker.csv"),
                "--format",
                "laser_tracker",
                "--plan",
                "training",
                "--campaign",
                "config/campaigns/recorded-tracker.yaml",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    ds = open_dataset(out, kind="run")
    assert (
        ds["time"].attrs["units"] == "seconds since 2026-03-02T10:00:00+00:00"
        and ds["time"].values[-1] == 350.0
    )
    capsys.readouterr()
    bad = tmp_path / "bad.nc"
    assert (
        main(
            [
                "import-recording",
                str(DATA / "stage2d_tracker.csv"),
                "--format",
                "laser_tracker",
                "--plan",
                "training",
                "--campaign",
                "config/campaigns/recorded-iso230.yaml",
                "--out",
                str(bad),
            ]
        )
        != 0
    )
    err = capsys.readouterr().err.strip()
    assert err.endswith(
        "holds a stage2d recording; campaign config/campaigns/recorded-iso230.yaml is 'stage1d'"
    )
    assert "\n" not in err and not bad.exists()


def test_huge_declared_sizes_are_refused_without_allocating():
    """20000 x 100000 readings declared (16 GB as floats), none given: refused, nothing allocated."""
    text = "UNIT=mm\nCYCLES=100000\nPOSITIONS=20000\n" + "".join(
        f"TGT_DATA[{i}]={i}\n" for i in range(1, 20001)
    )
    expect(
        "REF_DATA_FWD[1,1] missing; expected POSITIONS=20000 x CYCLES=100000",
        ecmc_iso230.parse,
        text,
        "big.dat",
    )
