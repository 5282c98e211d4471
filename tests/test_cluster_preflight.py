"""The SLURM pre-flight check reads sinfo's partition lines and names, in one sentence, the
partition that can start no job (calflow.cluster); the cluster itself is exercised by
``make cluster-test`` (tests/cluster), not here."""

import pytest

from calflow.cluster import check_partitions, parse_sinfo, partition_problem
from calflow.errors import ConfigError

# `sinfo -h -o "%P|%a|%T"` of a site: one line per partition and node state
SITE = "normal*|up|mixed\nnormal*|up|drained\ngpu|up|idle\nlong|down|idle\nbig|up|down*\nbig|up|idle*\n"


def test_parse_marks_the_default_and_gathers_node_states():
    partitions, default = parse_sinfo(SITE)
    assert default == "normal"
    assert partitions["normal"] == ("up", ["mixed", "drained"])
    assert set(partitions) == {"normal", "gpu", "long", "big"}


@pytest.mark.parametrize("partition", ["normal", "gpu", None])
def test_a_partition_with_a_node_that_takes_jobs_passes(partition):
    assert partition_problem(partition, SITE) is None


def test_a_missing_partition_is_named_with_the_ones_there_are():
    msg = partition_problem("nomral", SITE)
    assert "'nomral' does not exist" in msg and "big, gpu, long, normal" in msg and "\n" not in msg


def test_a_partition_set_down_starts_nothing():
    assert "'long' is down" in partition_problem("long", SITE)


def test_nodes_down_or_not_responding_leave_no_node():
    msg = partition_problem("big", SITE)
    assert "no node that can run a job" in msg and "down*" in msg and "idle*" in msg


def test_no_partition_and_no_default():
    assert "no default partition" in partition_problem(None, "gpu|up|idle\n")


def test_check_raises_one_line_for_the_first_bad_partition_and_ignores_repeats():
    with pytest.raises(ConfigError, match="'big' has no node") as err:
        check_partitions(["gpu", "big", "gpu", "", None], sinfo_text=SITE)
    assert "\n" not in str(err.value)
    check_partitions(["gpu", None, ""], sinfo_text=SITE)  # the default partition is up
    check_partitions([], sinfo_text="")  # nothing to submit, nothing asked
