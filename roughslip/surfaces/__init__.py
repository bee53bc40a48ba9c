"""Surfaces: synthetic topographies and their statistics (:mod:`.synthetic`), and measured
topographies read from instrument files (:mod:`.topography`)."""
