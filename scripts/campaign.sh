#!/usr/bin/env bash
# Run a Monte Carlo campaign of in-process team runs: random draws of a scenario, each for every
# controller case and sweep value, in parallel (docs/campaigns.md).
#   scripts/campaign.sh SPEC --out DIR [--runs N] [--workers K] [--cluster ADDRESS] [--quiet]
# SPEC: a campaign spec YAML file (keys: uh_campaign/uh_campaign/spec.py) or a bundled spec
# (campaign_paper_faults, campaign_delay_sweep, campaign_delay_sweep_none, campaign_delay_sweep_jitter,
# campaign_random_graphs).
# Output: DIR/campaign.sqlite (one row of metrics per run), DIR/scenarios/ (the resolved scenario of
# every draw, loadable on its own). Re-running the same command on DIR resumes. Report: uh-report DIR.
# --cluster tcp://HOST:8786 runs on a Dask cluster whose workers run this project's .venv
# (.venv/bin/dask scheduler, .venv/bin/dask worker tcp://HOST:8786).
# Exit status: 0 done, 1 could not go on (what is done is saved), 2 bad input, 130 interrupted.
# When every run is stored, writes the report too (uh-report DIR: DIR/report/; --no-report: not).
# Sets up .venv on first use and compiles the numba kernels into its cache.
set -euo pipefail
source "$(dirname "${BASH_SOURCE[0]}")/_venv.sh"
exec uh-campaign "$@"
