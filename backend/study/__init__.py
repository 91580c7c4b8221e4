"""The study domain: who may do what, accounts, the audit trail, blinding, counterbalancing,
withdrawal and the demonstration study; services the API routes call."""
