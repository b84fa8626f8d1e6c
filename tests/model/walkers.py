"""The most general walkers of docs/model.md section 2, one for each foot shape, on which the
equations of motion and the collision are checked (tests/model/test_equations.py,
tests/model/test_effects.py)."""

__all__ = ["FEET", "GENERAL"]

#: Hip width, lateral and fore-aft mass offsets and all products of inertia non-zero (SI units): with
#: torus (spool-rim) feet, the most general case of docs/model.md section 2.
GENERAL = dict(leg_length=0.15, hip_width=0.02, leg_mass=0.06, axle_mass=0.01,
               com_offset=(-0.005, 0.1, -0.11), inertia=(2e-4, 3e-4, 2e-4, 1e-5, 2e-5, 1e-5),
               slope=0.0785, gravity=9.81)
#: Foot shapes: a point, a sphere and a torus (radii in m).
FEET = {
    "point": dict(foot_radius=0.0, foot_lateral_radius=0.0),
    "sphere": dict(foot_radius=0.03, foot_lateral_radius=0.03),
    "torus": dict(foot_radius=0.03, foot_lateral_radius=0.005),
}
