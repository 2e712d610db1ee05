"""Tool-library transfer: a hierarchical (population) model of the contact law per holder type (issue #20).

Stage 1 is every combination's own ``identify`` fit (run through
:mod:`bayes_rcsa.batch`), stage 2 the population's posterior from the stored
stage-1 draws (:mod:`.stage2`), and :mod:`.predictive` turns it into a prior
(or zero-tap draws) for a new combination.  See docs/library.md.
"""
