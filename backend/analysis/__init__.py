"""Analysis of recorded trials: the study results, their files, lock events and the background
jobs that compute them; services the API routes and the CLI call."""
