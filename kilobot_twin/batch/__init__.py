"""The Monte Carlo engine: campaigns over parameter grids on a compiled kernel (bit-identical to
the NumPy core), over local cores or a Dask cluster."""

from .campaign import Campaign, load_results, run_campaign, save_results

__all__ = ["Campaign", "run_campaign", "save_results", "load_results"]
