"""The vectorised Monte Carlo engine: campaigns over parameter grids, sharded over cores."""

from .campaign import Campaign, load_results, run_campaign, save_results

__all__ = ["Campaign", "run_campaign", "save_results", "load_results"]
