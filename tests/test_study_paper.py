"""Khalil & Gautier (1991), the AID robot: the checks of the paper-reproduction study.

The tutorial ``notebooks/01_identifiable_parameters.ipynb`` shows these numbers; they are
checked here against facts that do not come from calib: Table 1 and the counts of the
paper (23 base parameters for position measurement, eq. 29 and Table 2), the geometry of
the robot (the regrouping coefficients are r7 = 0.21 m and its inverse) and Everett's
completeness formula (Everett, Driels & Mooring, ICRA 1987).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import calib
from calib.identification.identifiability import analyze_model
from calib.identification.parameters import Kind, Parameter, ParameterSet, paper_parameters

# Table 1 of the paper, rows j = 0..7 (frame 0 = base, frame 7 = end effector).
TABLE1_ALPHA = [0, 0, 90, 0, -90, 90, -90, 0]  # [deg]
TABLE1_D = [0, 0, 0, 0.3, 0, 0, 0, 0]  # [m]
TABLE1_R = [0, 0, 0, 0, 0.4, 0, 0, 0.21]  # [m]
R7 = TABLE1_R[7]


@pytest.fixture(scope="module")
def aid():
    chain = calib.load_chain("aid")
    return chain, calib.from_chain(chain)


@pytest.fixture(scope="module")
def paper():
    return calib.analyze("aid", measure="position", params="paper")


def test_aid_urdf_is_table_1(aid):
    chain, mdh = aid
    assert chain.n_revolute == 6 and chain.n_prismatic == 0
    assert list(mdh.sigma) == [-1, 0, 0, 0, 0, 0, 0, -1]
    assert np.allclose(np.degrees(mdh.alpha), TABLE1_ALPHA, atol=1e-9)
    assert np.allclose(mdh.d, TABLE1_D, atol=1e-12)
    assert np.allclose(mdh.r, TABLE1_R, atol=1e-12)
    assert np.allclose(mdh.theta, 0, atol=1e-12) and np.allclose(mdh.beta, 0, atol=1e-12)
    # z2 // z3 (alpha3 = 0) and z6 // z7 (alpha7 = 0): Hayati's beta in rows 3 and 7.
    assert [k for k in range(2, mdh.n + 2) if mdh.parallel[k]] == [3, 7]


def test_paper_set_has_23_base_parameters_of_30(aid, paper):
    _, mdh = aid
    assert paper.n_standard == 4 * (mdh.n + 2) - 2 == 30
    assert paper.n_base == 23  # Khalil & Gautier 1991, eq. 29 and Table 2


def test_the_point_on_the_last_axis_sees_no_theta6_theta7(paper):
    assert set(paper.zero) == {"theta6", "theta7"}


def test_regrouping_coefficients_follow_the_geometry(paper):
    def coefficient(base, other):
        return float(paper.B[paper.base.index(base), paper.others.index(other)])

    assert math.isclose(coefficient("theta1", "theta0"), 1.0, rel_tol=1e-9)
    assert math.isclose(coefficient("r0", "r1"), 1.0, rel_tol=1e-9)
    assert math.isclose(coefficient("theta5", "d6"), -1 / R7, rel_tol=1e-9)
    assert math.isclose(coefficient("r5", "alpha6"), R7, rel_tol=1e-9)
    assert math.isclose(coefficient("beta7", "d7"), 1 / R7, rel_tol=1e-9)
    regrouped = [n for n in paper.others if n not in paper.zero]
    assert sorted(regrouped) == sorted(["theta0", "r1", "alpha6", "d6", "d7"])


def test_qr_spectrum_splits_into_two_clusters(paper):
    last_kept, first_dropped = paper.gap
    assert last_kept > 1e10 * first_dropped and first_dropped < paper.tolerance < last_kept


def test_complete_model_reaches_everett_25(aid, paper):
    chain, _ = aid
    everett = 4 * chain.n_revolute + 2 * chain.n_prismatic + 3 - 2
    assert paper.on_last_axis
    assert paper.n_complete == paper.n_theory == everett == 25
    assert {sentence.split(":")[0] for sentence in paper.missing} == {"beta1", "y1"}
    full = calib.analyze("aid", measure="position", params="complete")
    assert full.n_base == full.n_complete == everett == 25
    assert full.missing == ()


def test_paper_set_plus_beta1_gives_24(aid):
    chain, mdh = aid
    paper_set = paper_parameters(mdh)
    plus_beta1 = ParameterSet("paper + beta1", (*paper_set.parameters, Parameter(1, Kind.BETA)))
    res24 = analyze_model(
        mdh,
        plus_beta1,
        calib.Measurement.of("position"),
        chain.random_configurations(100, seed=0),
        robot="aid",
    )
    assert res24.n_base == 24
    assert {s.split(":")[0] for s in res24.missing} == {"y1"}


def test_full_pose_27_with_the_paper_set_30_complete(aid):
    chain, _ = aid
    pose = calib.analyze("aid", measure="pose", params="paper")
    pose_full = calib.analyze("aid", measure="pose", params="complete")
    everett_pose = 4 * chain.n_revolute + 2 * chain.n_prismatic + 6
    assert pose.n_base == 27
    assert pose_full.n_base == pose_full.n_complete == pose.n_theory == everett_pose == 30
    assert {s.split(":")[0] for s in pose.missing} == {"beta1", "y1", "y7"}
