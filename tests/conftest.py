"""Shared test settings: hypothesis profiles (CI runs the default, deterministic one) and the
markers by place: everything under tests/ros runs real rclpy processes over DDS (``dds``), so
``tests/run.sh -m "not dds"`` runs the in-process suite alone."""

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile(
    "default", deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile(
    "thorough", deadline=None, max_examples=1000, suppress_health_check=[HealthCheck.too_slow]
)
settings.load_profile(os.environ.get("OST_HYPOTHESIS_PROFILE", "default"))

DDS = Path(__file__).parent / "ros"


def pytest_collection_modifyitems(items):
    for item in items:
        if DDS in Path(item.fspath).parents:
            item.add_marker(pytest.mark.dds)
