"""GCS 2.0 framing and parsing (PI MS249E §8.2, §8.3, §8.7) without any I/O."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from calflow.errors import RigError
from calflow.gcs.wire.protocol import (
    CommandFramer,
    GCSControllerError,
    GCSInvalidAxisError,
    GCSMotionNotAllowedError,
    GCSParameterSyntaxError,
    GCSPositionOutOfLimitsError,
    GCSProtocolError,
    GCSStoppedError,
    GCSUnknownCommandError,
    ReplyFramer,
    error_from_code,
    format_command,
    format_pairs,
    parse_axis_values,
    parse_bool,
    parse_int,
    parse_ready,
    split_command,
    strip_address,
)


def replies(framer: ReplyFramer) -> list[list[str]]:
    out = []
    while (r := framer.pop()) is not None:
        out.append(r)
    return out


# ------------------------------------------------------------------ reply framing
def test_multiline_continuation_is_one_reply():
    f = ReplyFramer()
    f.feed(b"1=1 \n2=1\n")
    assert replies(f) == [["1=1", "2=1"]]


def test_reply_incomplete_until_line_without_trailing_space():
    f = ReplyFramer()
    f.feed(b"1=1 \n")
    assert f.pop() is None and f.pending()
    f.feed(b"2=0")
    assert f.pop() is None
    f.feed(b"\n")
    assert f.pop() == ["1=1", "2=0"]
    assert not f.pending()


def test_several_replies_in_one_chunk_and_crlf_tolerated():
    f = ReplyFramer()
    f.feed(b"0\n1=2.5\r\nA \nB\n")
    assert replies(f) == [["0"], ["1=2.5"], ["A", "B"]]


@given(
    st.lists(
        st.lists(st.from_regex(r"[A-Za-z0-9_=.+-]{1,12}", fullmatch=True), min_size=1, max_size=4),
        min_size=1,
        max_size=5,
    ),
    st.lists(st.integers(min_value=1, max_value=7), min_size=1, max_size=40),
)
def test_any_chunking_reassembles_the_same_replies(expected, cuts):
    wire = b"".join((" \n".join(r) + "\n").encode() for r in expected)
    f, pos, i = ReplyFramer(), 0, 0
    while pos < len(wire):
        step = cuts[i % len(cuts)]
        f.feed(wire[pos : pos + step])
        pos, i = pos + step, i + 1
    assert replies(f) == expected


# ------------------------------------------------------------------ reply parsing
def test_axis_values_parsed_in_order():
    got = parse_axis_values(["1=12.5000", "2=-3"], command="POS?")
    assert got == {"1": 12.5, "2": -3.0} and list(got) == ["1", "2"]
    assert parse_axis_values(["X=1 ", "Y_2=0"], parse_bool) == {"X": True, "Y_2": False}


@pytest.mark.parametrize("lines", [["1:5"], ["=5"], ["1=abc"], ["1=1\x00"], ["a b=1"], ["\x1b[2J"], ["1="]])
def test_garbage_axis_values_raise_protocol_error(lines):
    with pytest.raises(GCSProtocolError) as info:
        parse_axis_values(lines, command="POS?")
    assert info.value.command == "POS?" and info.value.code is None


def test_reply_must_name_the_requested_axes():
    with pytest.raises(GCSProtocolError, match="expected"):
        parse_axis_values(["2=1.0"], command="POS?", expect=["1"])


def test_bool_values_must_be_0_or_1():
    with pytest.raises(GCSProtocolError):
        parse_axis_values(["1=2"], parse_bool, command="ONT?")


def test_int_and_hex_and_ready_replies():
    assert parse_int(["0"]) == 0 and parse_int(["15"]) == 15
    assert parse_int(["1F"], base=16) == 31 and parse_int(["0x3"], base=16) == 3
    assert parse_ready(["\xb1"]) is True and parse_ready(["\xb0"]) is False
    for bad in (["x"], ["1", "2"], ["1.5"]):
        with pytest.raises(GCSProtocolError):
            parse_int(bad, command="ERR?")
    with pytest.raises(GCSProtocolError):
        parse_ready(["1"])


def test_address_prefix_is_stripped_only_when_present():
    assert strip_address("0 1 1=12.5") == "1=12.5"
    assert strip_address("0 12 5") == "5"
    assert strip_address("1=12.5") == "1=12.5"
    assert strip_address("0") == "0" and strip_address("0 1") == "0 1"


# ------------------------------------------------------------------ errors
@pytest.mark.parametrize(
    "code,cls",
    [
        (1, GCSParameterSyntaxError),
        (2, GCSUnknownCommandError),
        (5, GCSMotionNotAllowedError),
        (7, GCSPositionOutOfLimitsError),
        (10, GCSStoppedError),
        (15, GCSInvalidAxisError),
    ],
)
def test_error_codes_map_to_classes(code, cls):
    exc = error_from_code(code, command="MOV 1 3", axis="1")
    assert type(exc) is cls and exc.code == code and exc.axis == "1"
    assert exc.command == "MOV 1 3" and f"GCS error {code} " in str(exc)
    assert isinstance(exc, RigError)


def test_code_5_message_and_unknown_codes():
    assert "servo off or axis not referenced" in str(error_from_code(5))
    exc = error_from_code(4711, command="XYZ")
    assert type(exc) is GCSControllerError and exc.code == 4711 and "4711" in str(exc)


# ------------------------------------------------------------------ commands
def test_format_command_and_pairs():
    assert format_command("POS?", ["1", "2"]) == b"POS? 1 2\n"
    assert format_pairs("MOV", {"1": 12.5, "2": -3}) == b"MOV 1 12.5 2 -3\n"
    assert format_pairs("MOV", {"1": 1e-7}) == b"MOV 1 0.0000001\n"
    assert format_pairs("SVO", {"1": True, "2": 0}) == b"SVO 1 1 2 0\n"


@pytest.mark.parametrize(
    "bad", [{"1": float("nan")}, {"1": float("inf")}, {"a b": 1.0}, {"1\nSTP": 1.0}, {"": 1.0}]
)
def test_format_rejects_unsafe_arguments(bad):
    with pytest.raises(ValueError):
        format_pairs("MOV", bad)


def test_format_command_rejects_injected_line_feed():
    with pytest.raises(ValueError):
        format_command("POS?", ["1\n#24"])


def test_command_framer_lines_single_bytes_and_splits():
    f = CommandFramer()
    assert f.feed(b"*IDN?\nPOS? 1\nERR?\n") == ["*IDN?", "POS? 1", "ERR?"]
    assert f.feed(b"MO") == [] and f.feed(b"V 1 2") == [] and f.feed(b"\n") == ["MOV 1 2"]
    assert f.feed(b"\x05\x07\x18") == ["#5", "#7", "#24"]
    assert f.feed(b"PO\x18S?\n") == ["#24", "POS?"]  # #24 acts at once, even mid-line
    assert f.feed(b"\n\r\n") == []


def test_split_command_is_case_insensitive():
    assert split_command("mov 1 2.5") == ("MOV", ["1", "2.5"])
    assert split_command("*idn?") == ("*IDN?", [])
    assert split_command("#24") == ("#24", [])
    assert split_command("\t") == ("", [])
