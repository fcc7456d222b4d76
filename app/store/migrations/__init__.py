"""Alembic migrations of the ChakaMo database (applied at start-up by :meth:`app.store.database.Database.migrate`)."""
