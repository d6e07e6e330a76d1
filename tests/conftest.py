"""Shared fixtures: catalog chains are loaded once per session (they are never mutated)."""

from __future__ import annotations

import functools

import pytest

from calib import catalog, from_chain, load_chain

ANALYSABLE = tuple(e.name for e in catalog() if e.expect_error is None and not e.is_tree)
"""Catalog chains calib can analyse."""

TREES = tuple(e.name for e in catalog() if e.expect_error is None and e.is_tree)
"""Catalog trees (several tools) calib can analyse."""


@functools.cache
def chain_of(name: str):
    return load_chain(name)


@functools.cache
def mdh_of(name: str):
    return from_chain(chain_of(name))


@pytest.fixture(params=ANALYSABLE)
def catalog_name(request) -> str:
    return request.param
