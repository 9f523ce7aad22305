"""nhgait.gaits.planning — Planning: the request's arguments, guesses and their screening, the
search over attempts."""
