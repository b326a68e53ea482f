"""Monte Carlo campaigns of in-process team runs (docs/campaigns.md).

- :mod:`.spec`: the campaign spec (YAML), its validation and the per-run draws;
- :mod:`.runner`: runs the work units in a local process pool or on a Dask cluster, resumably;
- :mod:`.worker`: what a worker runs: the cases of one resolved scenario, one row each;
- :mod:`.progress`: the progress line while a campaign runs and its summary at the end;
- :mod:`.cli`: ``uh-campaign``, which writes the campaign's report (:mod:`uh_report`) at the end.

The results file ``DIR/campaign.sqlite`` (one row per run) is read and written only through
:mod:`uh_team.campaign_store`, which the report reads too.
"""
