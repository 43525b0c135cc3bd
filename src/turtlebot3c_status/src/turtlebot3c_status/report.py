"""The status as people read it (a line per part) and as scripts read it (--json), and its exit status."""
import json
from typing import List

from turtlebot3c_status.checks import Part

OK_MARK, FAIL_MARK = "\u2714", "\u2718"  # check mark, ballot x


def text(parts: List[Part]) -> str:
    width = max(len(part.label) for part in parts)
    lines = []
    for part in parts:
        line = f"{OK_MARK if part.ok else FAIL_MARK} {part.label:<{width}}  {part.summary}"
        if not part.ok and part.fix:
            line += f" -> {part.fix}"
        lines.append(line)
    return "\n".join(lines) + "\n"


def as_json(parts: List[Part]) -> str:
    document = {"ok": all_well(parts),
                "parts": [{"part": part.key, "ok": part.ok, "summary": part.summary, "fix": part.fix or None,
                           "details": part.details} for part in parts]}
    return json.dumps(document, indent=2, default=str) + "\n"


def all_well(parts: List[Part]) -> bool:
    return all(part.ok for part in parts)


def exit_status(parts: List[Part]) -> int:
    return 0 if all_well(parts) else 1
