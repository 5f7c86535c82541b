import pytest

from taimill.physics.simulation import init_taichi


@pytest.fixture(scope="session", autouse=True)
def taichi_once():
    """ti.init once for the whole session (a second call invalidates fields)."""
    init_taichi()
