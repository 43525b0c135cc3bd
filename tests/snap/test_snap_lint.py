"""The snap as snapcraft would build it: schema, review-tools-like lint, and what every app needs."""
import re
import subprocess
import sys

import pytest
import yaml

from snapsim import lint, prime
from testkit import ros_harness

REPO = ros_harness.REPO

SNAPCRAFT_YAML = REPO / "snap" / "snapcraft.yaml"


@pytest.fixture(scope="module")
def primed(tmp_path_factory, monkeypatch_module):
    folder = tmp_path_factory.mktemp("snap-prime")
    monkeypatch_module.setenv("TURTLEBOT3C_BUILD_DIR", str(ros_harness.BUILD))
    meta = prime.build_prime(REPO, folder / "prime", sys.executable)
    return folder / "prime", meta


@pytest.fixture(scope="module")
def monkeypatch_module():
    with pytest.MonkeyPatch.context() as patch:
        yield patch


def project():
    return yaml.safe_load(SNAPCRAFT_YAML.read_text())


def install_defaults():
    """{key: default} from the install hook's `default KEY VALUE` lines."""
    text = (REPO / "snap" / "hooks" / "install").read_text()
    return dict(re.findall(r"^default ([a-z0-9-]+) (\S+)$", text, re.MULTILINE))


def test_snapcraft_yaml_matches_snapcrafts_core20_schema():
    done = subprocess.run([sys.executable, str(REPO / "tools" / "check_snapcraft_schema.py"), str(SNAPCRAFT_YAML)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert "SKIPPED" not in done.stdout


def test_prime_tree_passes_lint(primed):
    assert lint.lint(primed[0]) == []


def test_lint_notices_a_missing_or_non_executable_script(primed, tmp_path):
    broken = tmp_path / "prime"
    subprocess.run(["cp", "-a", str(primed[0]), str(broken)], check=True)
    (broken / "usr" / "bin" / "save_map.sh").unlink()
    (broken / "usr" / "bin" / "ros_network.sh").chmod(0o644)
    problems = lint.lint(broken)
    assert "app mapping: stop-command: usr/bin/save_map.sh is not a file in the snap" in problems
    assert "app core: command-chain: usr/bin/ros_network.sh is not executable" in problems


def test_local_scripts_are_organized_into_usr_bin(primed):
    local = sorted(path.name for path in (REPO / "snap" / "local").glob("*.sh"))
    assert sorted(path.name for path in (primed[0] / "usr" / "bin").glob("*.sh")) == local
    assert list(primed[0].glob("*.sh")) == []


def test_simulator_package_is_not_shipped(primed):
    assert not (primed[0] / "opt" / "ros" / "noetic" / "share" / "turtlebot3c_sim").exists()
    assert project()["parts"]["workspace"]["catkin-packages-ignore"] == ["turtlebot3c_sim"]


def test_every_app_has_the_ros_extension_ros_home_and_the_network_chain_after_ros1_launch(primed):
    meta = primed[1]
    for name, app in project()["apps"].items():
        assert app["extensions"] == ["ros1-noetic"], name
        assert app["environment"]["ROS_HOME"] == "$SNAP_USER_DATA/ros", name
        assert meta["apps"][name]["command-chain"][:3] == [
            "snap/command-chain/snapcraft-runner", "snap/command-chain/ros1-launch", "usr/bin/ros_network.sh"], name


def test_mapping_and_navigation_start_disabled_and_clean_up_when_stopped():
    apps = project()["apps"]
    assert apps["mapping"]["install-mode"] == apps["navigation"]["install-mode"] == "disable"
    assert apps["mapping"]["stop-command"] == "usr/bin/save_map.sh"
    assert apps["mapping"]["post-stop-command"] == "usr/bin/install_last_map.sh"
    assert int(apps["mapping"]["stop-timeout"].rstrip("s")) >= 60
    assert apps["mapping"]["stop-mode"] == "sigint-all"  # rosbag closes its bag on SIGINT only
    assert apps["navigation"]["post-stop-command"] == "usr/bin/mux_select.sh --input key_vel"
    assert apps["navigation"]["environment"]["MUX_INPUT"] == "nav_vel"


def test_description_documents_every_option_and_its_default():
    description = project()["description"]
    defaults = install_defaults()
    assert set(defaults) == {"simulation", "turtlebot3-model", "lds-model", "ros-master-host", "opencr-port",
                             "lds-port", "map"}
    entries = {key: " ".join(text.split()) for key, text in
               re.findall(r"^- ([a-z0-9-]+): (.*?)(?=^- |^$|\Z)", description, re.MULTILINE | re.DOTALL)}
    for key, value in defaults.items():
        shown = "<this machine's hostname>.local" if key == "ros-master-host" else value
        assert f"(default {shown})" in entries.get(key, ""), (key, entries.get(key))


def test_hooks_are_dash_scripts_and_executable():
    for hook in (REPO / "snap" / "hooks").iterdir():
        assert hook.read_text().startswith("#!/bin/sh\n"), hook.name
        assert hook.stat().st_mode & 0o111, hook.name


def test_every_local_script_is_used_by_an_app_or_another_script():
    text = SNAPCRAFT_YAML.read_text() + "".join(
        path.read_text() for folder in ("local", "hooks") for path in (REPO / "snap" / folder).iterdir())
    for script in (REPO / "snap" / "local").glob("*.sh"):
        uses = text.count(script.name) - script.read_text().count(script.name)
        assert uses > 0, f"{script.name} is shipped but nothing runs it"
