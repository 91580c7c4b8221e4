"""Lab integration: Lab Streaming Layer outlets and inlets, event markers, XDF import and
BIDS-motion export."""
