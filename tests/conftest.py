"""Shared fixtures: catalog chains are loaded once per session (they are never mutated)."""

from __future__ import annotations

import functools
import os

import pytest
from hypothesis import HealthCheck, Phase, settings

from calib import catalog, from_chain, load_chain

ANALYSABLE = tuple(e.name for e in catalog() if e.expect_error is None and not e.is_tree)
"""Catalog chains calib can analyse."""

TREES = tuple(e.name for e in catalog() if e.expect_error is None and e.is_tree)
"""Catalog trees (several tools) calib can analyse."""

COUPLED = (
    "mimic_arm",
    "pr2_left_fingertip",
    "romeo_left_finger",
    "tiago_pro_left_fingertip",
    "baxter_left_finger",
    "panda_right_finger",
)
"""Catalog chains through mimic joints (tests/test_mimic.py checks this list is complete)."""

INDEPENDENT = tuple(name for name in ANALYSABLE if name not in COUPLED)
"""Catalog chains of independent joints, where Everett's counts hold."""


@functools.cache
def chain_of(name: str):
    return load_chain(name)


@functools.cache
def mdh_of(name: str):
    return from_chain(chain_of(name))


@pytest.fixture(params=ANALYSABLE)
def catalog_name(request) -> str:
    return request.param


# CI: a fixed (derandomised) set of 60 examples per property, no deadline, and no shrinking so
# that a failing property costs seconds, not minutes; the failing example is printed in full.
# Set CALIB_HYPOTHESIS_PROFILE=calib-dev to shrink failures to a minimal example and draw more.
settings.register_profile(
    "calib-ci",
    max_examples=60,
    deadline=None,
    derandomize=True,
    database=None,
    phases=(Phase.explicit, Phase.generate),
    suppress_health_check=[HealthCheck.too_slow],
    report_multiple_bugs=False,
)
settings.register_profile(
    "calib-dev",
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
CI = settings.get_profile(os.environ.get("CALIB_HYPOTHESIS_PROFILE", "calib-ci"))
"""Settings of the property tests (hypothesis)."""


@pytest.fixture(scope="session")
def forty_planes():
    """TALOS sole to gripper touching 40 planes (6 touches each), registered."""
    import numpy as np

    from calib.calibration import contact_checks
    from calib.measurements.contact_campaign import simulate_contacts

    chain = load_chain("talos", base="left_sole_link", tool="gripper_left_base_link")
    data = simulate_contacts(chain, 240, "plane", contacts=40, noise_mrad=0.01, seed=1).data
    nominal = from_chain(chain)
    start, train, *_ = contact_checks.checked_registration(
        chain, nominal, data, None, np.eye(4), None
    )
    return nominal, start, train


def wide_state(model, start, x):
    """An ``ErrorModel``'s state at columns ``x`` from ``start``, not by its Jacobian's route.

    The own unknowns through ``model.own.apply``, then the MDH base values added to their
    parameters through ``ParameterSet.apply``.
    """
    import dataclasses

    import numpy as np

    own = model.own
    state = own.apply(start, x[: own.size()])
    dX = np.zeros(len(model.params))
    dX[[model.params.index(name) for name in model.base]] = x[own.size() :]
    return dataclasses.replace(state, mdh=model.params.apply(state.mdh, dX))


def wide_minus_measured(model, start, data, x):
    """Model - measured of an ``ErrorModel``'s columns moved by ``x`` (:func:`wide_state`)."""
    return -wide_state(model, start, x).residuals(data)
