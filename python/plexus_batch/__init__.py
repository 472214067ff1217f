"""plexus-batch: batch and multi-machine plexus renders on Dask distributed (docs/batch.md)."""

__version__ = "0.1.0"

from .batchfile import Batch, BatchError, Job, load  # noqa: E402
from .report import BatchInterrupted, BatchReport, JobReport  # noqa: E402

__all__ = [
    "Batch",
    "BatchError",
    "BatchInterrupted",
    "BatchReport",
    "Job",
    "JobReport",
    "load",
    "run_batch",
    "__version__",
]


def run_batch(*args, **kwargs):
    """`plexus_batch.runner.run_batch`, imported on first use so that parsing a batch file does not
    import Dask."""
    from .runner import run_batch as run

    return run(*args, **kwargs)
