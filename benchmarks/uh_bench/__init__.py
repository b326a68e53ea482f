"""Benchmarks of the UH stack (``scripts/bench.sh``): real-time factors, CPU, latency, memory.

Modules:

- :mod:`uh_bench.runs` -- a team run through ``uh_bringup.run_formation`` as a child process,
  with its real-time factor (the clock's log), the CPU seconds and peak memory of every node
  process (``UH_PROC_STATS_DIR`` records of :mod:`uh_runtime.procstats`) and the whole process
  tree's resource use (``os.wait4``);
- :mod:`uh_bench.probe` -- a DDS reader process that records the writers' source timestamps of
  every state and command of a real-time run: state-to-command latency, late and missed steps;
- :mod:`uh_bench.inprocess` -- the in-process reference simulation's real-time factor and the
  per-step cost of the controller and of the helicopter model;
- :mod:`uh_bench.suite` -- the sections of the benchmark and the results mapping;
- :mod:`uh_bench.results` -- the goals and their evaluation against the results;
- :mod:`uh_bench.tables` -- the markdown tables of the results.

Run ``PYTHONPATH=benchmarks python -P -m uh_bench [--quick]`` (what ``scripts/bench.sh`` does).
"""
