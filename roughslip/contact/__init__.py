"""Contact mechanics: the problem object (:mod:`.problem`), the squeeze (:mod:`.squeeze`), the
decoupled pull (:mod:`.pull`), the coupled model (:mod:`.coupled`), the method registries
(:mod:`.methods`) and the closed-form references (:mod:`.analytic`)."""
