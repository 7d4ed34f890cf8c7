"""Helpers shared by test modules: plain modules of scenes and tools, and fixture modules that
tests/conftest.py loads through pytest_plugins. No test module imports another test module."""
