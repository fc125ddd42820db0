"""``report``: the paper's Figures 6-11 from a calibration (``paper_figures`` core, ``report`` CLI)."""
