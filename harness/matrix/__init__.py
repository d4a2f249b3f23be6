"""The matrix: what a benchmark case is, how cases are chosen, and what each leaves behind.

- :mod:`.registry`: the problems and integrators, found through entry points and
  loaded defensively;
- :mod:`.line`: a problem spec (one problem at one parameter set, parsed from
  ``name:key=value,...`` and built through the registry) and a line (problem spec,
  formulation, integrator with its settings, mode): how both are identified,
  labelled and given a family, for cases and stored records alike;
- :mod:`.cases`: a case (problem, parameters, formulation, integrator, settings,
  tolerance or step), the presets and the expansion of a selection into cases;
- :mod:`.record`: the result record's fields, statuses and reasons;
- :mod:`.store`: the SQLite store that holds the records, converted at its boundary;
- :mod:`.provenance`: which installation and code version wrote a record.

The source documents' rows and the ``seeds`` preset's list of cases are above it
(:mod:`integrator_bench.harness.sources`): a preset that lists its cases
(:attr:`~.cases.Preset.listed`) is handed them.

May import: :mod:`integrator_bench.harness.errors`, ``.paths``, ``.version``,
``problems/`` and ``integrators/``; nothing else of the harness.
"""
