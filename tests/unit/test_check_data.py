"""The static checks' data lives in the repository: the rosdep and schema checks run in any clone,
fail when an input is missing, and the data is what refresh_check_data.py cuts from ../shared."""
import subprocess
import sys
from pathlib import Path

import pytest

# What the check tools import (tools/setup-env's virtualenv has both): tests/unit needs only what
# docs/developing.md lists, so without them this module skips.
pytest.importorskip("catkin_pkg")
pytest.importorskip("jsonschema")

REPO = Path(__file__).resolve().parents[2]
TOOLS = REPO / "tools"
SHARED = REPO.parent / "shared"


def run_tool(name, *args):
    return subprocess.run([sys.executable, str(TOOLS / name)] + [str(arg) for arg in args], cwd=REPO,
                          capture_output=True, text=True, timeout=120, check=False)


def test_both_checks_pass_on_the_data_kept_in_the_repository():
    assert run_tool("check_rosdep.py", "src").returncode == 0
    assert run_tool("check_snapcraft_schema.py", "snap/snapcraft.yaml").returncode == 0


@pytest.mark.parametrize("tool, args", [
    ("check_rosdep.py", ["src", "--rosdistro", "{missing}"]),
    ("check_snapcraft_schema.py", ["snap/snapcraft.yaml", "--schema", "{missing}"]),
    ("check_snapcraft_schema.py", ["{missing}"]),
])
def test_a_missing_input_fails_with_one_line_naming_it(tmp_path, tool, args):
    missing = tmp_path / "absent"
    done = run_tool(tool, *[arg.format(missing=missing) for arg in args])
    assert done.returncode == 1
    assert len(done.stderr.splitlines()) == 1 and str(missing) in done.stderr
    assert "Traceback" not in done.stderr


def test_the_kept_data_is_what_a_refresh_from_the_full_snapshot_writes(tmp_path):
    if not (SHARED / "rosdistro").is_dir() or not (SHARED / "snapcraft").is_dir():
        pytest.skip(f"no full snapshot at {SHARED} to compare with")
    done = run_tool("refresh_check_data.py", "--out", tmp_path)
    assert done.returncode == 0, done.stderr
    written = sorted(path.relative_to(tmp_path) for path in tmp_path.rglob("*") if path.is_file())
    kept = sorted(path.relative_to(TOOLS / "data") for path in (TOOLS / "data").rglob("*") if path.is_file())
    assert written == kept
    stale = [str(path) for path in written if (tmp_path / path).read_bytes() != (TOOLS / "data" / path).read_bytes()]
    assert not stale, f"tools/data is stale: run tools/refresh_check_data.py ({stale})"


def test_refreshing_without_the_snapshot_writes_nothing_and_says_why(tmp_path):
    done = run_tool("refresh_check_data.py", "--rosdistro", tmp_path / "absent", "--out", tmp_path / "out")
    assert done.returncode == 1 and "nothing written" in done.stderr
    assert not (tmp_path / "out").exists()
