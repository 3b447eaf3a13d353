"""Chaos, measured: the variational equations of a derived system, the Lyapunov spectrum
by Benettin's method and the fast indicators MEGNO, SALI and GALI.

- ``variational``: the tangent functions (J(y) times a block of tangent vectors, with
  the system's own right-hand side or gradients) written from the symbolic Jacobian of
  Hamilton's equations as LLVM IR and integrated by the compiled drivers as they stand;
- ``lyapunov``: a run of the extended state, renormalised by QR at intervals, with the
  running estimates.
"""
