"""Analysis of run files: power-law fits (:mod:`.fit`), summaries (:mod:`.summary`), bursts
(:mod:`.bursts`), plots (:mod:`.plotting`), tables for pandas and xarray (:mod:`.tables`),
topography reports (:mod:`.topography_report`) and the verification against exact solutions
(:mod:`.verify`)."""
