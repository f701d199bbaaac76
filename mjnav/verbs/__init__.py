"""The verbs of the ``mjnav`` command (:mod:`mjnav.cli`): one module per verb, each with its options
dataclass (its keys, documented in ``Attributes:``), ``grammar()`` and ``run(parsed, argv)``."""
