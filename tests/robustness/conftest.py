"""Fixtures of the fault suite: one rendered demo-like project per test module, copied for each
test (a test may cut, flip or remove its files)."""
import pytest

from tests.robustness import faults as ft


@pytest.fixture(scope="module")
def master(tmp_path_factory):
    return ft.shared_sim(tmp_path_factory)


@pytest.fixture()
def sim(master, tmp_path):
    return ft.copy_sim(master, tmp_path / "sim")
