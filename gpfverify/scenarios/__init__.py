"""Reference systems of the toolkit's own (the papers' scenarios are in :mod:`gpfverify.papers`)."""
