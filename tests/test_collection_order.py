"""The order the suite hands its test files to the xdist workers (tests/conftest.py)."""

from types import SimpleNamespace

from tests import conftest


def _item(nodeid: str, slow: bool = False):
    return SimpleNamespace(nodeid=nodeid,
                           get_closest_marker=lambda name: object() if slow and name == "slow"
                           else None)


def test_files_of_end_to_end_tests_come_first_and_each_file_keeps_its_order():
    items = [_item("tests/a.py::t1"), _item("tests/a.py::t2"), _item("tests/a.py::t3"),
             _item("tests/b.py::t1", slow=True), _item("tests/b.py::t2"),
             _item("tests/c.py::t1"), _item("tests/c.py::t2"),
             _item("tests/d.py::t1", slow=True), _item("tests/d.py::t2", slow=True)]
    conftest.pytest_collection_modifyitems(None, items)
    assert [i.nodeid for i in items] == [
        "tests/d.py::t1", "tests/d.py::t2",  # two end-to-end tests
        "tests/b.py::t1", "tests/b.py::t2",  # one
        "tests/a.py::t1", "tests/a.py::t2", "tests/a.py::t3",  # then by number of tests
        "tests/c.py::t1", "tests/c.py::t2"]


def test_xdist_keeps_that_order(pytestconfig):
    # pytest-xdist would otherwise sort the files by their number of tests again.
    assert getattr(pytestconfig.option, "loadscopereorder", False) is False
