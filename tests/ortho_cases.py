"""Shared by the orthographic-camera tests (test_orthographic.py, test_orthographic_passes.py): the two
projections, the raster guard both modules ran under when they were one, and a camera's frame."""
import pytest

from helpers import reach_the_raster_guard

PROJECTIONS = ("perspective", "orthographic")


@pytest.fixture(scope="module", autouse=True)
def raster_guard():
    """This module feeds the raster NaN, infinite and huge vertices on purpose (helpers.reach_the_raster_guard)."""
    with pytest.MonkeyPatch.context() as mp:
        reach_the_raster_guard(mp)
        yield


def _frame_of(camera):
    right, up, back = camera.basis()
    return right, up, -back
