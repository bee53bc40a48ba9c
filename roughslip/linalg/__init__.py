"""Linear algebra independent of the physics: conjugate gradients on masked systems
(:mod:`.cg`), restricted operators with the SciPy ``LinearOperator`` contract
(:mod:`.restricted`), the updatable explicit inverse on a changing index set (:mod:`.inverse`),
the inverse of a drifting non-symmetric matrix from a nearby one (:mod:`.near`), 64-bit LAPACK
(:mod:`.lapack64`), thread pools (:mod:`.threads`) and the memory budget (:mod:`.memory`)."""
