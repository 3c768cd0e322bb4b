"""Alembic migrations of toaster's schema (run them with ``toaster db upgrade``)."""
