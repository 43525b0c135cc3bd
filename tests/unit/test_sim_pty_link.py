"""The fake devices' serial link: a pulled cable's pty number is not handed to the next pty opened."""
import os

import pytest

from turtlebot3c_sim.pty_link import PtyLink


def open_descriptors():
    return len(os.listdir("/proc/self/fd"))


def test_a_host_pointed_at_an_unplugged_pty_finds_no_device_rather_than_the_next_pty(tmp_path):
    link = PtyLink(tmp_path / "ttyACM0")
    link.plug()
    unplugged = link.slave_name
    link.unplug()
    assert not (tmp_path / "ttyACM0").exists()
    master, slave = os.openpty()  # the kernel hands out the lowest free number
    try:
        assert os.ttyname(slave) != unplugged
        with pytest.raises(FileNotFoundError):
            os.close(os.open(unplugged, os.O_RDWR | os.O_NOCTTY))
    finally:
        os.close(master)
        os.close(slave)
        link.close()


def test_close_lets_go_of_every_pty_the_link_had(tmp_path):
    before = open_descriptors()
    link = PtyLink(tmp_path / "ttyACM0")
    for _ in range(3):
        link.plug()
        link.unplug()
    link.plug()
    link.close()
    assert not link.plugged and open_descriptors() == before
