"""Default limits of a run, in a module light enough for the command line's parser."""

DEFAULT_MAX_STEPS = 10**8
"""The step budget of a command-line run: about 3 s of leapfrog, a minute of Gauss-Legendre."""

DEFAULT_ENERGY_TOLERANCE = 1e-2
"""A run whose relative energy error exceeds this stops with ``"energy_error"``."""

MIN_T_END = 1e-300
"""The shortest run: a tenth of it, the longest default step, is still a normal float
(an end time of 5e-324 made a step of 0)."""
