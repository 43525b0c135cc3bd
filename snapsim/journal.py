"""The system journal: one JSON line per message, tagged with the service unit."""
import datetime
import json
import os
import threading


def unit_name(snap, app):
    return f"snap.{snap}.{app}.service"


def write(layout, unit, ident, pid, message):
    record = {
        "t": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="microseconds"),
        "unit": unit, "ident": ident, "pid": pid, "msg": message,
    }
    layout.journal.parent.mkdir(parents=True, exist_ok=True)
    line = (json.dumps(record) + "\n").encode()
    fd = os.open(layout.journal, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
    try:
        os.write(fd, line)  # one write with O_APPEND: lines from several writers never interleave
    finally:
        os.close(fd)


def follow_stream(layout, unit, ident, pid, stream):
    """Copy a process's output to the journal, line by line, in a background thread."""
    def pump():
        with stream:
            for raw in iter(stream.readline, b""):
                write(layout, unit, ident, pid, raw.decode(errors="replace").rstrip("\n"))
    thread = threading.Thread(target=pump, daemon=True)
    thread.start()
    return thread


def read(layout):
    try:
        with open(layout.journal) as stream:
            return [json.loads(line) for line in stream if line.endswith("\n")]
    except FileNotFoundError:
        return []


def format_record(record):
    stamp = record["t"].replace("+00:00", "Z")
    return f"{stamp} {record['ident']}[{record['pid']}]: {record['msg']}"
