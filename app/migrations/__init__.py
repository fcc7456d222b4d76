"""Alembic migrations of the ChakaMo database (applied at start-up by :meth:`app.db.Database.migrate`)."""
