"""The pull of the decoupled model: the bonds of a squeeze (:mod:`.bonds`), the event loop of
the exact piecewise-linear models (:mod:`.events`), the slip laws (:mod:`.laws`) and their
pulls (:mod:`.breaking`, :mod:`.breaking_single`, :mod:`.sliding`, :mod:`.weakening`),
:func:`~roughslip.friction.pull.pull` and its estimates (:mod:`.pull_estimates`)."""
