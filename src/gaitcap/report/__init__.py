"""The self-contained HTML gait report and its matplotlib figures."""
