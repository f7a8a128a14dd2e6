"""The reduction of the assembled bodies to the contact interface (docs/theory.md
sections 3-4, 8, 10-11).

- :mod:`.schur`: the Schur complement of a sparse SPD stiffness, one module per
  backend behind a registry (:func:`~.schur.schur_complement`);
- :mod:`.congruence`: bodies equal up to an orthogonal map share one factor;
- :mod:`.condensation`: each body condensed onto its interface DOFs, recovery;
- :mod:`.two_bodies`: the two-body relative-displacement problem ``lam = K d + W a``;
- :mod:`.multibody`: several bodies and interfaces as one contact problem;
- :mod:`.rigid`: bodies held only through the joint, free-free assemblies;
- :mod:`.pretension`: bolts locked after the preload.
"""
