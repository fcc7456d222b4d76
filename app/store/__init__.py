"""Persistence: the database (``database``, ``models``, Alembic ``migrations``), the content-addressed blob store
(``blobs``), stored sessions as folders the pipeline reads (``workspace``) and the queries the API's routes call
(``queries``)."""
