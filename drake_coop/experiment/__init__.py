"""The experiment: references (28)-(29), the whole Diagram (diagram) and its simulation (simulate)."""
