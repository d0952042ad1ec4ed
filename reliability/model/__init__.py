"""The machine model: transforms, kinematics (exact chain and Jacobian, tool or workpiece
frame), the machine description, poses, ISO 230-1 names, error profiles along travel,
measured profiles, correlation and the draws of errors.

Built on :mod:`reliability.basics` only.
"""
