"""The robot model: an immutable tree of joints and bodies with symbolic inertial parameters."""
