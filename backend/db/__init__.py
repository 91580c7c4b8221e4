"""Storage: the engine, the ORM models and the migrations that create them."""
