"""The REST API: ``create_app(session, settings)`` builds the FastAPI application."""

from .app import create_app as create_app
