"""Independent verification of :mod:`fem_grasp`: ``python -m verification STUDY [options]``.

Everything here sits beside the package and imports it, never the other way round.  One subpackage per
study, each with a README.md (what it checks, against what, the command):

``dolfinx``        fem_grasp's K, G, strain energies and contact solves against FEniCSx/dolfinx, entry by entry;
                   manufactured solutions, locking and stability
``hertz``          a sphere squeezed between rigid planes against Hertz theory; a fingertip pressed into a block
``roundoff``       the same answer under round-off perturbations
``random_scenes``  random valid scenes never crash
``converge``       convergence of the pickup answer under refinement
``coverage``       the accuracy loop's stated error against a finer reference, on random objects
``friction``       frictional contact against an independent reference solver
``softness``       finger forces at lift-off against the rigid grasp (Table III of the paper)

``all`` (:mod:`verification.report`) runs every study into one report; :mod:`verification._common` holds what
they share (HTML, pictures, running stages).
"""
