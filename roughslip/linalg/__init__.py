"""Linear algebra independent of the physics: conjugate gradients on masked systems
(:mod:`.cg`), restricted operators with the SciPy ``LinearOperator`` contract
(:mod:`.restricted`), 64-bit LAPACK (:mod:`.lapack64`), thread pools (:mod:`.threads`) and the
memory budget (:mod:`.memory`)."""
