"""The coupled normal-tangential model: the solvers of its reduced block
(:mod:`.blocksolvers`), its contact and stick sets (:mod:`.state`), the squeeze histories
(:mod:`.histories`) and :func:`~roughslip.coupling.coupled.couple` (:mod:`.coupled`)."""
