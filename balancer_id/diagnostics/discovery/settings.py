"""The discovery's thresholds and names (one place for its modules)."""

#: A kept term must lower the BIC of the linear step by at least this (as the arena's
#: :data:`~balancer_id.diagnostics.diagnosis.BIC_THRESHOLD`).
TERM_BIC = 30.0
#: BIC by which a discovered law must beat a library dry-friction law that reached the
#: noise floor (:func:`challenges`). Both are dry friction: the choice is of its shape,
#: and the discovered law's extra parameters are already counted in its BIC. 10 is
#: "very strong" on Kass and Raftery's scale; where the library's law is the truth, the
#: two extra parameters of Coulomb with Stribeck reach it by chance with a probability of
#: about exp(-(10 + 2 ln n) / 2) (n the independent samples, thousands in a log).
CHALLENGE_BIC = 10.0
#: Terms tried at most along the pursuit path.
MAX_TERMS = 4
#: Terms the linear step ranks highest that are refitted whole in each round.
REFITTED = 3
#: ... those whose linear BIC fall is at least this share of the best one's.
CLOSE = 0.3
#: A term refitted whole within this BIC of the chosen one fits about as well.
CLOSE_BIC = 10.0
#: Bootstrap resamples of the trials for the inclusion probabilities.
BOOTSTRAP = 40
#: Stribeck velocities, as shares of the highest speed the trials reach.
STRIBECK_GRID = (0.02, 0.07, 0.25)
#: The error above the noise floor (x the noise) that the arena's best may leave before
#: discovery is tried (the level test's tolerance, adequacy.LEVEL_MIN).
LEFT_OVER = 0.5
#: Samples (at most, by a regular stride) of the residual force's spectrum over position.
PERIOD_SAMPLES = 3000
#: The Coulomb term, and the prefix of the Stribeck terms (tried with it as a pair).
COULOMB, STRIBECK = "f_c", "f_st"
#: Terms tried only when the residual's spectrum over position has a period.
PERIODIC = ("a_sin", "a_cos")
#: Marker of a file written by ``improve --discover`` (only such a file is ever replaced).
MARKER = "# Written by balancer-id improve --discover."
