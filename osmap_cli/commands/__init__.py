"""The `osmap` commands, one module each, all of the same shape: click options -> a builder that
checks every option and plans every output before any work -> jobs (osmap_cli.batch.Job) run by
osmap_cli.batch.run_jobs. `common` holds what several commands share (size types, batch and
tuning flags, preset loading, output planning). osmap_cli.cli imports these modules lazily.
"""
