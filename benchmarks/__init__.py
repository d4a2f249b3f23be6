"""asv benchmarks of integrator-bench, generated from the registries.

See ``cases.py`` for the suite and the README's "Performance over commits"
section for the commands.
"""
