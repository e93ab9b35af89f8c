"""Contact points from collision geometry (jaxskid.collision_points) against Pinocchio's own reading of the same
URDFs (buildGeomFromUrdf: hpp-fcl shapes placed on the joints), and a floating base that lands on its collision
points instead of falling through the floor."""

import warnings

import jax
import jax.numpy as jnp
import numpy as np
import pinocchio as pin
import pytest
from helpers import ERD

import jaxskid
from jaxskid.apps.simulation._contact import NEEDED

SOLO12 = ERD / "solo_description/robots/solo12.urdf"
GO1 = ERD / "go1_description/urdf/go1.urdf"
FEET = ("FL_FOOT", "FR_FOOT", "HL_FOOT", "HR_FOOT")
STAND = np.array([0, 0.8, -1.6, 0, 0.8, -1.6, 0, -0.8, 1.6, 0, -0.8, 1.6])


def pinocchio_shapes(urdf):
    """Per link: [(shape type, its pose in the link's frame, hpp-fcl shape)] from Pinocchio's collision model."""
    model = pin.buildModelFromUrdf(str(urdf), pin.JointModelFreeFlyer())
    geom = pin.buildGeomFromUrdf(model, str(urdf), pin.COLLISION, package_dirs=[str(ERD.parents[1])])
    shapes = {}
    for g in geom.geometryObjects:
        frame = model.frames[g.parentFrame]
        in_link = frame.placement.inverse() * g.placement
        shapes.setdefault(frame.name, []).append((type(g.geometry).__name__, in_link.homogeneous, g.geometry))
    return shapes


@pytest.mark.parametrize("urdf", [GO1, SOLO12], ids=["go1", "solo12"])
def test_points_match_pinocchio_collision_model(urdf):
    """Boxes and meshes by the corners of Pinocchio's local bounding box, spheres by their centre and radius,
    cylinders by rim points on their end circles."""
    points = jaxskid.collision_points(urdf)
    shapes = pinocchio_shapes(urdf)
    assert {link for link, _ in points.frames.values()} == set(shapes)
    for link, elements in shapes.items():
        for i, (kind, pose, shape) in enumerate(elements):
            names = [n for n in points.frames if n.startswith(f"{link}_collision{i}_")]
            ours = np.array([np.linalg.solve(pose, points.frames[n][1])[:3, 3] for n in names])  # in the shape's frame
            radii = np.array([points.radius[n] for n in names])
            if kind == "Sphere":
                assert np.allclose(ours, 0, atol=1e-12) and np.allclose(radii, shape.radius)
            elif kind == "Cylinder":
                assert len(ours) == 16 and np.allclose(radii, 0)
                assert np.allclose(np.hypot(ours[:, 0], ours[:, 1]), shape.radius)
                assert np.allclose(np.abs(ours[:, 2]), shape.halfLength)
            else:  # a box, or a mesh's bounding box
                shape.computeLocalAABB()
                low, high = shape.aabb_local.min_, shape.aabb_local.max_
                corners = np.array([[(low, high)[a][0], (low, high)[b][1], (low, high)[c][2]]
                                    for a in (0, 1) for b in (0, 1) for c in (0, 1)])
                assert len(ours) == 8 and np.allclose(radii, 0)
                assert np.allclose(np.sort(ours, axis=0), np.sort(corners, axis=0), atol=1e-7)


def test_errors_name_the_file_and_link(tmp_path):
    with pytest.raises(jaxskid.ModelError, match=r"solo12.urdf: links: unknown link 'base_lnk' \(did you mean "
                                                 r"'base_link'"):
        jaxskid.collision_points(SOLO12, links=["base_lnk"])
    text = """<robot name="r"><link name="a"><collision><geometry><mesh filename="missing.stl"/></geometry>
        </collision></link><link name="b"><collision><geometry><box size="0.1 -0.2 0.1"/></geometry></collision>
        </link><link name="c"/></robot>"""
    path = tmp_path / "r.urdf"
    path.write_text(text)
    with pytest.raises(jaxskid.ModelError, match=r"r.urdf: link\[name=a\].collision\[0\].geometry.mesh: the mesh "
                                                 r"'missing.stl' .* could not be read"):
        jaxskid.collision_points(path)
    with pytest.raises(jaxskid.ModelError, match=r"link\[name=b\].collision\[0\].geometry.box.size: expected "
                                                 r"positive dimensions, got '0.1 -0.2 0.1'"):
        jaxskid.collision_points(path, links=["b"])
    with pytest.raises(jaxskid.ModelError, match=r"link\[name=c\]: expected <collision> geometry"):
        jaxskid.collision_points(path, links=["c"])


@pytest.fixture(scope="module")
def solo_with_base():
    base = jaxskid.collision_points(SOLO12, links=["base_link"])
    robot = jaxskid.load(SOLO12, floating_base=True, end_effectors={**{f: (f, None) for f in FEET}, **base.frames})
    assert robot.end_effectors[:4] == FEET
    dyn = jaxskid.lower(robot, ["forward_dynamics", *NEEDED])
    return dyn, base


def test_a_base_with_collision_points_lands_on_them(solo_with_base):
    """solo12 dropped upside down (its legs held up by a PD law): with its feet alone as contacts the base passes
    through the floor and the rollout says so; with the corners of the base mesh's bounding box it comes to rest
    on the bounding box's top face (z = 0.028 m in the base frame), up to the springs' sag."""
    dyn, base = solo_with_base

    def hold(t, x):
        return jnp.concatenate([jnp.zeros(6), -3.0 * (x[7:dyn.nq] - STAND) - 0.05 * x[dyn.nq + 6:]])

    x0 = np.zeros(dyn.nq + dyn.nv)
    x0[2], x0[3:7], x0[7:dyn.nq] = 0.1, [1.0, 0, 0, 0], STAND  # 180 degrees about x: the base's top face down
    feet_only = jaxskid.GroundContact(dyn, FEET, inner=hold)
    assert feet_only.on_base() == ()
    with pytest.warns(jaxskid.RolloutWarning, match=r"floating base of the rollout ends below the ground .* none of "
                                                    r"GroundContact's frames \(FL_FOOT, FR_FOOT, HL_FOOT, HR_FOOT\)"):
        fallen = jaxskid.rollout(dyn, x0, feet_only, 1e-3, 600)
    assert fallen.x[-1, 2] < -0.1

    landing = jaxskid.GroundContact(dyn, {**dict.fromkeys(FEET, 0.0), **base.radius}, inner=hold)
    assert set(landing.on_base()) == set(base.frames) and "(12 in all)" in repr(landing)
    with warnings.catch_warnings():
        warnings.simplefilter("error", jaxskid.RolloutWarning)
        traj = jaxskid.rollout(dyn, x0, landing, 1e-3, 600, health=False)
        assert not jaxskid.apps.simulation._health.warn_if_below_ground(landing, traj.x[-1])
    weight = 9.81 * pin.computeTotalMass(pin.buildModelFromUrdf(str(SOLO12), pin.JointModelFreeFlyer()))
    sag = weight / (4 * landing.k)  # the weight on the four corners of the face, each a spring k
    z = np.asarray(traj.x[:, 2])
    mass = weight / 9.81
    impact = np.sqrt(2 * 9.81 * (0.1 - 0.028)) * np.sqrt(mass / (4 * landing.k))  # undamped spring's compression
    assert z.min() > 0.028 - impact > 0
    assert abs(z[-1] - (0.028 - sag)) < 2 * sag
    assert np.abs(np.asarray(traj.x[-1, dyn.nq:dyn.nq + 6])).max() < 0.05
    _, f, _ = jax.jit(landing.forces)(traj.x[-1, :dyn.nq], traj.x[-1, dyn.nq:])
    assert np.all(np.asarray(f[:4]) == 0) and abs(float(jnp.sum(f[:, 2])) - weight) < 0.05 * weight
