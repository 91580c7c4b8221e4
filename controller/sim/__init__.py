"""The simulated wearer and exoskeleton: participants, activities, biomechanics and the plant."""
