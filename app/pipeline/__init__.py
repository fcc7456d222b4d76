"""The session pipeline: recordings in (``ingestion``), numbers out (``session``), files written (``results``,
``render``, ``process``), plus the simulated ``demo`` and the live ``view``.  Knows nothing of the database or
the web; the store, the job engines and the CLI call it."""
