"""A Python file without any cosim hook: it defines no effect."""

VALUE = 1
