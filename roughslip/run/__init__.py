"""Runs: the configuration (:mod:`.config`), the scene it describes (:mod:`.scene`), the
stages that compute one sample (:mod:`.stages`), the executors that run samples in processes or
on a cluster (:mod:`.executor`), the output schema (:mod:`.schema`) and the HDF5 store
(:mod:`.store`)."""
