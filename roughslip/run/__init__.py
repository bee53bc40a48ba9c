"""Runs: the configuration (:mod:`.config`), the scene it describes (:mod:`.scene`), the
stages that compute one sample (:mod:`.stages`, run by :mod:`.sample`), the executors that run
samples in this process, in a process pool or on a cluster (:mod:`.executor`, :mod:`.pool`,
:mod:`.cluster`), the output schema (:mod:`.schema`) and the HDF5 store (:mod:`.store`)."""
