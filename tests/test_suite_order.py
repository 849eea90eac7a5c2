"""The suite's schedule under pytest-xdist: the test files ordered by their measured
cost (`tests/durations.json`), and pytest-xdist's file scheduler handing them out in
that order (with its reordering by number of tests off, as `tests/conftest.py` sets)."""

import json
from types import SimpleNamespace

import pytest

from .conftest import DURATIONS, longest_files_first


def _items(*nodeids):
    return [SimpleNamespace(nodeid=n) for n in nodeids]


def test_files_are_ordered_by_the_cost_of_their_collected_tests():
    items = _items("a.py::1", "a.py::2", "b.py::1", "c.py::1", "c.py::2", "d.py::1")
    durations = {
        "a.py::1": 1.0,
        "a.py::2": 1.0,
        "b.py::1": 5.0,
        "c.py::1": 1.0,
        "c.py::2": 0.5,
        "c.py::3": 100.0,  # not collected (deselected): does not count
    }
    longest_files_first(items, durations)
    # b (5) > a (2) > c (1.5) > d (not in the table: last); a file's tests keep
    # their order and stay together
    assert [i.nodeid for i in items] == [
        "b.py::1",
        "a.py::1",
        "a.py::2",
        "c.py::1",
        "c.py::2",
        "d.py::1",
    ]


class _Node:
    def __init__(self, dispatched: list):
        self.shutting_down = False
        self.sent = []
        self.dispatched = dispatched
        self.gateway = SimpleNamespace(id=f"gw{len(dispatched)}-{id(self)}")

    def send_runtest_some(self, indices):
        self.sent.extend(indices)
        self.dispatched.append(list(indices))

    def shutdown(self):
        self.shutting_down = True


def _handed_out(reorder: bool, collection: list[str]) -> list[str]:
    """The files in the order pytest-xdist's `loadfile` scheduler hands them out to
    two workers that finish their tests one by one, in turn."""
    from xdist.scheduler import LoadFileScheduling

    config = SimpleNamespace(
        option=SimpleNamespace(loadscopereorder=reorder),
        getvalue=lambda name: ["2*popen"],
    )
    sched = LoadFileScheduling(config)
    dispatched: list[list[int]] = []
    nodes = [_Node(dispatched), _Node(dispatched)]
    for node in nodes:
        sched.add_node(node)
        sched.add_node_collection(node, collection)
    sched.schedule()
    while any(node.sent for node in nodes):
        for node in nodes:
            if node.sent:
                sched.mark_test_complete(node, node.sent.pop(0))
    files = [collection[batch[0]].split("::", 1)[0] for batch in dispatched]
    assert sorted(files) == sorted(set(files))  # one file, one worker
    return files


def test_xdist_hands_the_files_out_in_the_collection_order():
    pytest.importorskip("xdist")
    # a long file of 1 test, a short file of 3: the cost order puts the long one first
    collection = ["long.py::1", "short.py::1", "short.py::2", "short.py::3", "x.py::1"]
    assert _handed_out(False, collection) == ["long.py", "short.py", "x.py"]
    # xdist's default: by number of tests, which would put the long file last
    assert _handed_out(True, collection) == ["short.py", "long.py", "x.py"]


def test_the_cost_table_is_readable():
    # test ids to CPU seconds; an entry of a renamed or removed test is ignored
    durations = json.loads(DURATIONS.read_text())
    assert durations and all(
        isinstance(k, str) and "::" in k and v >= 0 for k, v in durations.items()
    )
