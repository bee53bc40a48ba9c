"""Contact mechanics: the problem object (:mod:`.problem`), the squeeze (:mod:`.squeeze`) and
its estimates (:mod:`.estimates`), the method registries (:mod:`.methods`) and the closed-form
references (:mod:`.analytic`). The pull is in :mod:`roughslip.friction`, the coupled model in
:mod:`roughslip.coupling`."""
