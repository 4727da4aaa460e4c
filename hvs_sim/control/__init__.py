"""Control: IBVS on point features and camera twist → Jaco joint velocities. Pure numpy."""

from hvs_sim.control.arm import ArmDriver, ArmLimits, JointCommand, twist_to_joint_velocities  # noqa: F401
from hvs_sim.control.features import interaction_matrix  # noqa: F401
from hvs_sim.control.laws.ibvs import IBVSConfig, IBVSController  # noqa: F401
