"""The MRPT peers' runner (benchmarks/mrpt_peers.py): which failures are kept as the peer's answer."""
import pytest

from benchmarks import mrpt_peers


@pytest.mark.parametrize("script, kept", [("exit 3", True), ("kill -ABRT $$", True),
                                          ("kill -TERM $$", False), ("kill -KILL $$", False)])
def test_a_peer_that_fails_by_itself_is_kept_failed_but_not_one_stopped_from_outside(tmp_path, script, kept):
    with pytest.raises(RuntimeError) as failure:
        mrpt_peers._run(["sh", "-c", script], tmp_path / "peer.out")
    assert isinstance(failure.value, mrpt_peers.PeerFailed) == kept
