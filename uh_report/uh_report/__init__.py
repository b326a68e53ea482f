"""Reports of runs and campaigns (docs/report.md, docs/campaigns.md).

- :mod:`.bag_metrics`: a recorded team bag back to arrays, and the metrics of a run from it;
- :mod:`.report`: ``uh-report`` for a run (bag or ``uh-simulate`` output) or a campaign directory;
- :mod:`.report_figures`: the figures of a run's report;
- :mod:`.campaign_report`: the statistics, figures and tables of a campaign's report.
"""
