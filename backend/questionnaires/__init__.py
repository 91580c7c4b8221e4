"""Questionnaires as data: a validated definition format, the scoring it describes, and
the built-in instruments (SUS; the EUS with the project's own wording)."""
