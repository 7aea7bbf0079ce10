"""DDS tests: every test gets its own ROS_DOMAIN_ID (lock directory) and LOCALHOST discovery."""

import pytest

from tests.ros.dds_helpers import Processes, free_domain, release_domain


@pytest.fixture
def domain():
    d = free_domain()
    yield d
    release_domain(d)


@pytest.fixture
def procs(tmp_path, domain):
    p = Processes(tmp_path, domain)
    yield p
    p.stop()
