"""Parameter sweeps: a kernel (a batched closed loop) over a design of knobs and seeds, distributed
with Dask, written as one tidy Parquet table. :mod:`.spec` reads the spec and lays out the runs,
:mod:`.kernels` holds the kernels, :mod:`.distribute` runs the tasks and assembles the table."""
