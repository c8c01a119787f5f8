"""The ``outcast`` command line (:mod:`outcast_core.runtime.cli.main`) and its sub-commands."""
