"""Monte Carlo campaigns of in-process team runs (docs/campaigns.md).

- :mod:`.store`: the results file ``DIR/campaign.sqlite`` (one row per run), read and written only
  through this module;
- :mod:`.spec`: the campaign spec (YAML), its validation and the per-run draws;
- :mod:`.runner`: runs the work units in a local process pool or on a Dask cluster, resumably;
- :mod:`.cli`: ``uh-campaign``.
"""
