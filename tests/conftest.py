"""Shared fixtures: catalog chains are loaded once per session (they are never mutated)."""

from __future__ import annotations

import functools

import pytest

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
