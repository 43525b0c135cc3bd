"""snapsim's configuration: snap set/get/unset typing, snapctl output rules, hooks' transactions."""
import json

import pytest

from testkit.ros_harness import wait_until
from testkit.snap_system import SnapSystem, make_demo_project, trace


@pytest.fixture(scope="module")
def system(tmp_path_factory):
    folder = tmp_path_factory.mktemp("snapsim-config")
    system = SnapSystem(folder / "root")
    system.snapsim("install", make_demo_project(folder / "demo"), "--dangerous")
    yield system
    system.shutdown()


def snapctl(system, *args):
    """snapctl as the demo's `tool` app runs it (through its command-chain)."""
    script = 'snapctl "$@"; echo "rc=$?"'
    done = system.snapsim("run", "--shell", "demo.tool", "-c", script, "_", *args)
    output, _, rc = done.stdout.rpartition("rc=")
    return output, int(rc), done.stderr


def test_set_decodes_json_values_and_keeps_other_text_as_strings(system):
    system.snapsim("set", "demo", "number=1", "flag=true", "quoted=\"1\"", "text=LDS-01", "object={\"a\": [1, 2]}",
                   "nan=NaN", "trailing=1 2")
    values = system.config("demo")
    assert values["number"] == 1 and values["flag"] is True and values["quoted"] == "1"
    assert values["text"] == "LDS-01" and values["object"] == {"a": [1, 2]}
    assert values["nan"] == "NaN" and values["trailing"] == "1 2"


def test_set_with_s_keeps_strings_and_with_t_requires_json(system):
    system.snapsim("set", "-s", "demo", "forced=true")
    assert system.config("demo")["forced"] == "true"
    refused = system.snapsim("set", "-t", "demo", "strict=not-json", check=False)
    assert refused.returncode == 1 and "failed to parse JSON" in refused.stderr
    assert "strict" not in system.config("demo")


@pytest.mark.parametrize("assignment", ["Upper=1", "a..b=1", "trail-=1", "double--dash=1", "9=1", "under_score=1"])
def test_set_rejects_invalid_option_names(system, assignment):
    done = system.snapsim("set", "demo", assignment, check=False)
    assert done.returncode == 1 and "invalid option name" in done.stderr


def test_dotted_keys_make_nested_options_and_unset_removes_them(system):
    system.snapsim("set", "demo", "nested.inner.value=5", "nested.other=x")
    assert system.config("demo")["nested"] == {"inner": {"value": 5}, "other": "x"}
    system.snapsim("set", "demo", "nested.other!")
    system.snapsim("unset", "demo", "nested.inner")
    assert "nested" not in system.config("demo")


def test_snap_get_of_a_missing_option_is_an_error(system):
    done = system.snapsim("get", "demo", "missing", check=False)
    assert done.returncode == 1 and 'snap "demo" has no "missing" configuration option' in done.stderr


def test_snapctl_get_prints_strings_raw_and_other_values_as_json(system):
    system.snapsim("set", "demo", "text=hello", "number=7", "object={\"b\": 1, \"a\": true}")
    assert snapctl(system, "get", "text")[:2] == ("hello\n", 0)
    assert snapctl(system, "get", "number")[:2] == ("7\n", 0)
    assert snapctl(system, "get", "object")[0] == '{\n\t"a": true,\n\t"b": 1\n}\n'


def test_snapctl_get_of_an_unset_option_prints_an_empty_line_or_null_with_t(system):
    assert snapctl(system, "get", "unset-option")[:2] == ("\n", 0)
    assert snapctl(system, "get", "-t", "unset-option")[0] == "null\n"
    assert snapctl(system, "get", "-t", "text")[0] == '"hello"\n'


def test_snapctl_get_with_d_or_several_keys_prints_a_document(system):
    assert json.loads(snapctl(system, "get", "-d", "text")[0]) == {"text": "hello"}
    assert json.loads(snapctl(system, "get", "text", "number", "unset-option")[0]) == {
        "text": "hello", "number": 7, "unset-option": ""}


def test_snapctl_set_from_an_app_applies_at_once(system):
    assert snapctl(system, "set", "from-app=42")[1] == 0
    assert system.config("demo")["from-app"] == 42


def test_rejected_set_leaves_configuration_unchanged_and_shows_the_hook_message(system):
    before = system.config("demo")
    done = system.snapsim("set", "demo", "color=green", "other=1", check=False)
    assert done.returncode == 1
    assert 'Run configure hook of "demo" snap' in done.stderr
    assert "color: 'green' is not allowed; allowed values: red, blue" in done.stderr
    assert system.config("demo") == before


def test_snapctl_restart_in_configure_waits_until_the_hook_ends(system):
    first = system.wait_state("demo", "svc", ["active"])["main_pid"]
    start = len(trace(system))
    system.snapsim("set", "demo", "restart-svc=true")
    wait_until(lambda: system.status("demo", "svc")["main_pid"] not in (None, first), 30, "svc never restarted")
    wait_until(lambda: "command" in trace(system)[start:], 30, "restarted svc never ran its command")
    since = trace(system)[start:]
    assert since.index("configure-end") < since.index("stop-command") < since.index("command")
    system.snapsim("unset", "demo", "restart-svc")
