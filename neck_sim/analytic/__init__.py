"""The paper's analytic model of the N-X neck (sections 3 and 4, errata fixed), pure numpy, batched.

Sign conventions are written once in :mod:`neck_sim.analytic.cables`.  The model holds within the
joint range: every function that takes joint angles refuses |alpha| > ``geometry.alpha_max`` with
:class:`PoseRangeError` unless called with ``allow_outside_range=True`` (finite differences at the
edge, drawing a diverged estimate).
"""

from neck_sim.analytic.cables import (cable_kinematics, cable_lengths, elongation, motor_angles_rigid,
                                      transmission_matrix, transmission_matrix_dot)
from neck_sim.analytic.dynamics import (ElasticState, bias_forces, cable_stiffness, cable_tension,
                                        elastic_derivative, elongation_series, elongation_step,
                                        gravity_spring_torque, kinetic_energy, linkage_dynamics, mass_matrix,
                                        motor_friction, potential_energy, rigid_acceleration, simulate_elastic,
                                        simulate_rigid, static_elongation)
from neck_sim.analytic.estimation import (UnreachableError, estimate_alpha_pinv, estimate_alpha_triangular,
                                          pinv_increment)
from neck_sim.analytic.geometry import (Kinematics, PoseRangeError, forward_kinematics, joint_corners, psi,
                                        side_lengths)

__all__ = [
    "cable_kinematics", "cable_lengths", "elongation", "motor_angles_rigid", "transmission_matrix",
    "transmission_matrix_dot", "ElasticState", "bias_forces", "cable_stiffness", "cable_tension",
    "elastic_derivative", "elongation_series", "elongation_step", "static_elongation",
    "gravity_spring_torque", "kinetic_energy", "linkage_dynamics", "mass_matrix", "motor_friction",
    "potential_energy", "rigid_acceleration", "simulate_elastic", "simulate_rigid", "UnreachableError",
    "estimate_alpha_pinv", "estimate_alpha_triangular", "pinv_increment", "Kinematics",
    "forward_kinematics", "joint_corners", "psi", "side_lengths", "PoseRangeError",
]
