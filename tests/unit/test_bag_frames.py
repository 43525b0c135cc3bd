"""The LIDAR's pose on the base through a bag's frame tree (bag_inputs.frame_in_base), as remap_bag
(whole 3-D transforms: a LIDAR may hang upside down) and localize_bag (planar poses) read it."""
import math

import pytest

from turtlebot3c_common.bag_inputs import frame_in_base
from turtlebot3c_common.se2 import compose
from turtlebot3c_navigation.amcl_replay import sensor_offset_in_tree
from turtlebot3c_slam.bag_replay import Transform3D, mount_in_tree

PLANAR_TREE = {"base_link": ("base_footprint", (0.0, 0.0, 0.0)),
               "base_scan": ("base_link", (-0.032, 0.0, math.pi / 2)),
               "lidar_optical": ("base_scan", (0.1, 0.0, 0.0))}


def test_the_chain_is_composed_from_the_base_outwards():
    assert frame_in_base(PLANAR_TREE, "base_footprint", "/lidar_optical", (0.0, 0.0, 0.0), compose) == \
        pytest.approx((-0.032, 0.1, math.pi / 2))
    scan = sensor_offset_in_tree(PLANAR_TREE, "base_footprint", "base_scan")
    assert scan == pytest.approx((-0.032, 0.0, math.pi / 2))
    assert sensor_offset_in_tree(PLANAR_TREE, "base_footprint", "base_footprint") == (0.0, 0.0, 0.0)


@pytest.mark.parametrize("tree", [
    {"base_scan": ("base_link", (0.0, 0.0, 0.0))},                                        # no base_link -> base
    {"base_scan": ("a", (0.0, 0.0, 0.0)), "a": ("b", (0.0, 0.0, 0.0)), "b": ("a", (0.0, 0.0, 0.0))},  # a loop
], ids=["chain-stops-short", "chain-loops"])
def test_a_chain_that_does_not_reach_the_base_gives_none(tree):
    assert sensor_offset_in_tree(tree, "base_footprint", "base_scan") is None
    assert mount_in_tree({child: (parent, Transform3D((0, 0, 0), (0, 0, 0, 1))) for child, (parent, _) in tree.items()},
                         "base_footprint", "base_scan") is None


def test_a_lidar_hung_upside_down_through_two_links_is_found_so():
    half_turn_about_x = (1.0, 0.0, 0.0, 0.0)
    tree = {"base_link": ("base_footprint", Transform3D((0.1, 0.0, 0.0), (0.0, 0.0, 0.0, 1.0))),
            "base_scan": ("base_link", Transform3D((0.0, 0.0, 0.2), half_turn_about_x))}
    x, y, yaw, upside_down = mount_in_tree(tree, "base_footprint", "base_scan")
    assert (x, y, yaw) == pytest.approx((0.1, 0.0, 0.0)) and upside_down
