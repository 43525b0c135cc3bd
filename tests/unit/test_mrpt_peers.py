"""The MRPT peers' runner (benchmarks/mrpt_peers.py): which failures are kept as the peer's answer,
how a run's settings are written, how pf-localization's estimates are read, and when a log's
rawlog is written."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks import mrpt_peers


@pytest.mark.parametrize("script, kept", [("exit 3", True), ("kill -ABRT $$", True),
                                          ("kill -TERM $$", False), ("kill -KILL $$", False)])
def test_a_peer_that_fails_by_itself_is_kept_failed_but_not_one_stopped_from_outside(tmp_path, script, kept):
    with pytest.raises(RuntimeError) as failure:
        mrpt_peers._run(["sh", "-c", script], tmp_path / "peer.out")
    assert isinstance(failure.value, mrpt_peers.PeerFailed) == kept


def test_pf_localization_estimates_are_read_from_its_log_one_per_scan_in_radians():
    log = "\n".join([
        "[05:32:06.4732|INFO |MonteCarloLocalization_Rawlog] PDF estimation: (1.428,0.285,2.36deg), ESS (B.R.)= 0",
        "[05:32:06.8450|INFO |MonteCarloLocalization_Rawlog] Odometry estimation: (0.500,0.000,-9.00deg)",
        "[05:32:06.8457|INFO |MonteCarloLocalization_Rawlog] PDF estimation: (-0.937,-1e-2,-180.00deg), ESS= 2",
    ])
    estimates = mrpt_peers.pf_localization_estimates(log)
    assert estimates.shape == (2, 3)
    assert estimates[0] == pytest.approx([1.428, 0.285, math.radians(2.36)])
    assert estimates[1] == pytest.approx([-0.937, -0.01, -math.pi])


def test_a_peer_config_sets_keys_of_its_own_section_only(tmp_path):
    template = tmp_path / "template.ini"
    template.write_text("[MappingApplication]\nlogOutput_dir = x\n[LocalizationExperiment]\n"
                        "logOutput_dir = out   // replaced\nmap_file = m\n")
    written = mrpt_peers._config(template, tmp_path / "run.ini", {"logOutput_dir": "/tmp/run"},
                                 section_name="[LocalizationExperiment]")
    assert written.read_text().splitlines() == [
        "[MappingApplication]", "logOutput_dir = x", "[LocalizationExperiment]", "logOutput_dir = /tmp/run",
        "map_file = m"]
    with pytest.raises(ValueError):
        mrpt_peers._config(template, tmp_path / "bad.ini", {"rawlog_file": "r"},
                           section_name="[LocalizationExperiment]")


def test_a_logs_rawlog_is_written_once_per_set_of_inputs(tmp_path, monkeypatch):
    written = []

    def write_rawlog(log, odometry, path, max_range):
        written.append(max_range)
        path.write_text("rawlog")

    monkeypatch.setattr(mrpt_peers, "write_rawlog", write_rawlog)
    log = SimpleNamespace(stamps=np.arange(3.0), ranges=np.ones((3, 4)), angle_min=-1.5, angle_increment=1.0)
    odometry = np.zeros((3, 3))
    first = mrpt_peers.rawlog_in(tmp_path, log, odometry)
    assert mrpt_peers.rawlog_in(tmp_path, log, odometry) == first
    assert written == [mrpt_peers.MAX_RANGE]
    # Another severity's odometry, or another range, in the same folder: a rawlog of its own.
    other_odometry = mrpt_peers.rawlog_in(tmp_path, log, odometry + 0.1)
    other_range = mrpt_peers.rawlog_in(tmp_path, log, odometry, 80.0)
    assert len({first, other_odometry, other_range}) == 3
    assert written == [mrpt_peers.MAX_RANGE, mrpt_peers.MAX_RANGE, 80.0]
