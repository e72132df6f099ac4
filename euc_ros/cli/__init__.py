"""The ``euc-ros`` command line: one module per subcommand (:mod:`euc_ros.cli.main` dispatches)."""
