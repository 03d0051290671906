"""Readers and writers only: no maths lives here."""
