"""Muscle activity on the server: recording files, montages, imports, live EMG, MVC."""
