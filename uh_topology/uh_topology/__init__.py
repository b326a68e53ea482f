"""The team of a run: scenarios, the communication graph and its checks (docs/graph.md, docs/scenario.md).

``scenario`` (with ``scenario_keys``, ``scenario_team`` and ``schema``): loading and validating a
scenario file and its gains, campaign and impairment files; ``graph``: adjacency, Laplacian blocks,
reachability (Assumption 1) and containment weights (Lemma 1); ``impairments``: what each
controller receives; ``generate``: generated teams of any size; ``errors``: the exception types;
``config/``: the bundled scenarios, gains and campaign specs.
"""
