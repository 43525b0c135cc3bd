"""The suite's longest modules are handed to xdist's workers first, not last (testkit.scheduling)."""
from pathlib import Path
from types import SimpleNamespace

from testkit.scheduling import LONGEST_MODULES, LongestModulesFirst

REPO = Path(__file__).resolve().parents[2]


class TwoWorkerConfig:
    option = SimpleNamespace(loadscopereorder=True)  # xdist's default: most tests first

    def getvalue(self, name):
        return {"tx": ["2*popen"]}[name]


class Worker:
    def __init__(self, name, collection):
        self.gateway = SimpleNamespace(id=name)
        self.collection = collection
        self.shutting_down = False
        self.modules = []

    def send_runtest_some(self, indexes):
        self.modules.append(self.collection[indexes[0]].split("::")[0])

    def shutdown(self):
        self.shutting_down = True


def first_modules_handed_out(collection):
    scheduler = LongestModulesFirst(TwoWorkerConfig())
    workers = [Worker("gw0", collection), Worker("gw1", collection)]
    for worker in workers:
        scheduler.add_node(worker)
        scheduler.add_node_collection(worker, collection)
    scheduler.schedule()
    return [worker.modules[0] for worker in workers]


def test_a_long_module_of_one_test_goes_first_and_the_next_longest_to_the_other_worker():
    many_short_tests = [f"tests/unit/test_planner.py::test_{index}" for index in range(30)]
    long_ones = ["tests/snap/test_e2e_demo.py::test_demo", "tests/snap/test_convergence.py::test_twenty_runs"]
    assert first_modules_handed_out(many_short_tests + long_ones) == [
        "tests/snap/test_convergence.py", "tests/snap/test_e2e_demo.py"]


def test_every_module_named_exists():
    assert [module for module in LONGEST_MODULES if not (REPO / module).is_file()] == []
