"""The plausibility metrics, one module each.

A module holds one report name's metric: its class (stable ``name``, ``unit``,
what it reads, ``thresholds`` under a
:class:`~simenv.plausibility.metric.ScoreConfig`, and a docstring giving its
math), the code of that math, and for a joint-level metric its kernel spec
(``*_spec``: how the one compiled pass runs it). ``ground_penetration`` and
``floating`` hold two classes, the geom version and the keypoint version.
The scorer runs the list in :mod:`simenv.plausibility.metric_registry`;
``docs/plausibility.md`` ("Adding a metric") says how to add one.

=================== ======================================================
module              report name and what it measures
=================== ======================================================
bone_length         source bones keeping their length
foot_skate          a low foot sliding (GMD skating ratio, PhysDiff skate)
ground_penetration  lowest geom / keypoint below the floor
floating            airborne without a free-fall arc
jitter              windows of high normalized jerk (ProtoMotions)
velocity            speeds beyond human limits, teleports
joint_limits        hinge angles beyond anatomical ranges that the motion demands
self_penetration    overlap of non-neighbouring geoms of one body
root_residual       root force no floor contact explains (inverse dynamics)
balance             centre of mass outside the support when quasi-static
tracking            an unassisted simulated body following the motion
inter_penetration   overlap between two people's geoms
contact             key joint-pair distance error (JPD) of two people
pair_root_residual  root help floor and partner's hands cannot give
=================== ======================================================
"""
