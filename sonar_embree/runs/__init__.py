"""Runs: TOML configs (:mod:`.runconfig`), sweeps (:mod:`.sweep`), batches on Dask (:mod:`.batch`), the
command line (:mod:`.cli`) and the built-in demo scene (:mod:`.demo`)."""
