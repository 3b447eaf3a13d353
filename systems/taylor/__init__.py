"""Taylor-series integration generated from the derivation (issue 28): the Taylor
decomposition of Hamilton's equations (``decompose``), the coefficients' recurrences and
a numpy reference evaluator (``coefficients``), and a plain reference integrator
(``reference``). The compiled family is built on these; see docs/internals.md."""
