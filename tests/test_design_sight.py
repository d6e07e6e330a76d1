"""The line of sight of an instrument the robot carries (TIAGo's head camera seeing its hand).

The reference is Pinocchio's model of the URDF and coal alone: the camera and the point placed
at each posture by Pinocchio's forward kinematics, a capsule between them checked against
every collision geometry but the hand's (the point's tool and what it carries) and the head's
(the camera's own body). calib drew the capsule from the camera where its reference posture
puts it, whatever the head joints, and counted the head's mesh, which holds the camera, as an
obstacle: 90 % of the postures were hidden by the head itself.
"""

from __future__ import annotations

import coal
import numpy as np
import pinocchio as pin
from pinref import pin_config

from calib import InvalidArgumentError, load_chain
from calib.design.collision import SIGHT_RADIUS, collision_checker
from calib.design.constraints import Constraints
from calib.design.design import design
from calib.kinematics.catalog import erd_robots_dir

CAMERA, TOOL = "xtion_optical_frame", "arm_tool_link"
OWN = ("head_2_link", "arm_tool_link", "wrist_ft", "hand_")  # the head's, the hand's: not obstacles
MARKER = np.array([0.0, 0.0, 0.1])  # on the hand, 10 cm past the flange
BOX = (-0.35, -0.25, 0.3, 0.35, 0.25, 1.0)  # in front of the camera (z forward) [m]


def _hidden(chain, q: np.ndarray) -> np.ndarray:
    """Whether a geometry (not the head's, not the hand's) crosses the camera-marker segment."""
    urdf = str(chain.urdf_path)
    model = pin.buildModelFromUrdf(urdf)
    package = str(erd_robots_dir().parent.parent)
    geom = pin.buildGeomFromUrdf(model, urdf, pin.GeometryType.COLLISION, package_dirs=[package])
    data, gdata = model.createData(), pin.GeometryData(geom)
    ids = [model.getJointId(n) for n in chain.joint_names]
    cam, tool = model.getFrameId(CAMERA), model.getFrameId(TOOL)
    others = [g for g in geom.geometryObjects if not g.name.startswith(OWN)]
    out = []
    for qi in q:
        x = pin_config(model, ids, qi)
        pin.framesForwardKinematics(model, data, x)
        pin.updateGeometryPlacements(model, data, geom, gdata, x)
        a, b = data.oMf[cam].translation, data.oMf[tool].act(MARKER)
        length = float(np.linalg.norm(b - a))
        z = (b - a) / length
        R = pin.Quaternion.FromTwoVectors(np.array([0.0, 0.0, 1.0]), z).matrix()
        capsule = coal.Capsule(SIGHT_RADIUS, length)
        tf = coal.Transform3s(R, (a + b) / 2)
        hit = False
        for g in others:
            pl = gdata.oMg[geom.getGeometryId(g.name)]
            result = coal.CollisionResult()
            where = coal.Transform3s(pl.rotation, pl.translation)
            hit = (
                hit
                or coal.collide(capsule, tf, g.geometry, where, coal.CollisionRequest(), result) > 0
            )
        out.append(hit)
    return np.array(out)


def test_a_head_cameras_sight_is_drawn_where_each_posture_puts_the_camera():
    """At postures whose hand is in front of the camera, calib's line of sight hides exactly
    the postures the reference hides (the arm between the camera and the hand), a third."""
    chain = load_chain("tiago", CAMERA, TOOL)
    q = chain.random_configurations(1500, 3)
    T = chain.tool_placements(q)
    points = T[:, :3, :3] @ MARKER + T[:, :3, 3]  # in the camera frame
    ahead = np.all((points >= BOX[:3]) & (points <= BOX[3:]), axis=1)
    q, points = q[ahead], points[ahead]
    assert len(q) > 100
    expected = _hidden(chain, q)
    assert 0.1 < expected.mean() < 0.6  # the arm hides some, not all
    found = collision_checker(chain).blocked(q, points[:, None, :], np.zeros(3))
    assert found.tolist() == expected.tolist()


def test_a_point_no_line_of_sight_reaches_is_explained():
    """The TIAGo's arm_tool_link origin lies inside arm_6_link's collision mesh: every
    candidate is hidden, and the error says why and what to do; a point on the hand is seen."""
    chain = load_chain("tiago", CAMERA, TOOL)
    sight = Constraints(workspace=BOX, line_of_sight=(0.0, 0.0, 0.0))
    try:
        design(chain, 15, marker=np.zeros(3), constraints=sight, seed=1)
    except InvalidArgumentError as e:
        assert "line_of_sight rejects" in str(e) and "inside a link's collision geometry" in str(e)
        assert "\n" not in str(e)
    else:
        raise AssertionError("a point inside the wrist's mesh was planned")
    plan = design(chain, 15, marker=MARKER, constraints=sight, seed=1)
    assert len(plan.q) == 15
