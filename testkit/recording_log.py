"""A stand-in for the logger the drivers' plain-Python cores take (rospy's in the nodes)."""


class RecordingLog:
    """Keeps every line as (level, message), for tests to read back."""

    def __init__(self):
        self.lines = []

    def info(self, message):
        self.lines.append(("info", message))

    def warning(self, message):
        self.lines.append(("warning", message))

    def error(self, message):
        self.lines.append(("error", message))
