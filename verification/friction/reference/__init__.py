"""The independent frictional-contact reference: quasi-static Coulomb contact as a sequence of static problems.

:mod:`.body`     the elastic body from dolfinx's K and G, condensed onto its surface, with its rigid modes
:mod:`.contact`  one static contact problem: a semismooth Newton method on the Alart–Curnier equations
:mod:`.pickup`   rest, squeeze, lift test and lift of Algorithm 1 as sequences of static problems

It shares no code with fem_grasp's contact modules; it takes from fem_grasp's result only the placement
(formulation: ``verification/friction/README.md``).
"""
