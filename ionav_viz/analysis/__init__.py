"""Analysis: the paper's metrics, manoeuvre detection, running estimators on outages, reports and tables."""
