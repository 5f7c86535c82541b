import pytest


@pytest.fixture(scope="session")
def taichi():
    """ti.init once for the session, for tests that call Taichi kernels directly (a
    second ti.init would invalidate fields). Runs, runners and the live mill start
    Taichi themselves; NumPy-only tests never do."""
    from taimill.physics.runner import init_taichi

    init_taichi()
