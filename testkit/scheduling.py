"""The order in which xdist hands test modules to its workers (tools/test runs `--dist loadfile`).

xdist hands out the modules with the most tests first. Our longest modules hold a few long tests
each (a test that installs the snap 20 times, the end-to-end demos), so they came last; one then
ran alone on one worker while the other had nothing left to do. The convergence test alone held
the suite about 280 s so. The modules below go first instead, longest first. The figures, in
seconds on 2 workers (2026-11-28), say where each belongs when they change.
"""
from xdist.scheduler import LoadFileScheduling

LONGEST_MODULES = (
    "tests/snap/test_convergence.py",           # 284
    "tests/snap/test_e2e_demo.py",              # 182
    "tests/snap/test_snap_configure.py",        # 160
    "tests/unit/test_slam_real_data.py",        # 135
    "tests/snap/test_maps_snap.py",             # 129
    "tests/snap/test_status_snap.py",           # 126
    "tests/unit/test_amcl_real_data.py",        # 121
    "tests/snap/test_master_daemon.py",         # 112
    "tests/snap/test_convergence_property.py",  # 97
)


class LongestModulesFirst(LoadFileScheduling):
    """xdist's loadfile scheduling, with LONGEST_MODULES at the head of the queue."""

    def _assign_work_unit(self, node):
        # The queue (module -> its tests) is built and then handed out within one call of
        # schedule(), so it is put in order here, just before each module is handed out.
        for module in reversed(LONGEST_MODULES):
            if module in self.workqueue:
                self.workqueue.move_to_end(module, last=False)
        super()._assign_work_unit(node)
