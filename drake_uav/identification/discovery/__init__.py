"""The search for the effects a model lacks: the candidate effects, the baseline design,
the evidence rule, parsimony, plausibility and adequacy, and the loop that runs them.

* :mod:`.effects` and :mod:`.vector_effects`: the effect libraries (per coefficient, and
  jointly on several coefficients).
* :mod:`.coefficient_design`: the baseline design of each coefficient and its fit.
* :mod:`.loop`: :func:`~.loop.discover`, the search itself.
* :mod:`.result`: what it returns (:class:`~.result.DiscoveryResult`,
  :class:`~.result.FoundEffect`, :class:`~.result.EvidenceRule`).
* :mod:`.parsimony`, :mod:`.plausibility`, :mod:`.adequacy`, :mod:`.fitted_point`: the
  checks the loop applies.

Imports the samples, the thrust model and the statistics, never the assessment or the
pipeline.
"""
