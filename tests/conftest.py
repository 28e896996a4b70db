from __future__ import annotations

import pytest

from dsg_hil.physics.params import load_params


@pytest.fixture(scope="session")
def params():
    return load_params()
