"""The decision (the paper's "Calculating Utilities" and "Making Decisions"): the
utility function U(a, category, s_n) of the four lock actions and the expected
utilities the controllers maximise."""
