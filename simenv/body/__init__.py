"""The simulated body: the subject-fitted humanoid, inverse kinematics, retargeting and
rendering."""
