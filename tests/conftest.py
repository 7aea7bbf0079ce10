"""Shared test settings: hypothesis profiles (CI runs the default, deterministic one)."""
import os

from hypothesis import HealthCheck, settings

settings.register_profile("default", deadline=None, derandomize=True,
                          suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("thorough", deadline=None, max_examples=1000,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("OST_HYPOTHESIS_PROFILE", "default"))
