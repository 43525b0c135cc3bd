"""A damaged copy of a good ROS 1 bag, for the tools that read bags to refuse in one line."""


def with_frame_names_not_utf8(good, path):
    """Copy the bag `good` to `path` with its frame names turned into bytes that are not UTF-8: its
    records still parse, its messages do not (rosbags then raises whatever its parser trips over)."""
    path.write_bytes(good.read_bytes().replace(b"base_footprint", b"\xff" * len(b"base_footprint")))
    return path
