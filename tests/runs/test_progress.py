"""Progress bars on a terminal, silence in logs."""

import io

from calflow.acquisition.progress import progress


class _Terminal(io.StringIO):
    def isatty(self):
        return True


def test_a_log_file_gets_nothing():
    stream = io.StringIO()
    with progress("run", 10, stream) as step:
        for i in range(10):
            step(i + 1, 10)
    assert stream.getvalue() == ""


def test_a_terminal_gets_a_bar_with_the_count():
    stream = _Terminal()
    with progress("nano1d training", 4, stream) as step:
        for i in range(4):
            step(i + 1, 4)
    out = stream.getvalue()
    assert "nano1d training" in out and "4/4" in out
