"""Persistence: the database (``database``, ``models``, Alembic ``migrations``), the content-addressed blob store
(``blobs``), stored sessions as folders the pipeline reads (``workspace``) and the data layer the API's routes
call, one module per resource: ``accounts`` (tokens, browser sessions, users), ``patients``, ``sessions``
(scoping, status, the busy rule), ``recordings``, ``analyses`` (and their artefacts, superseded ones), ``audit`` (the log's
rows), ``erasure`` (reference-counted, crash-safe erasure of stored files), ``retention`` (the policy) and ``checks`` (the ingestion check of stored files and its freshness).  Their refusals are the
classes of ``errors`` (no HTTP here: the API maps them to status codes).  Nothing here imports ``app.web``
or ``app.jobs``."""
