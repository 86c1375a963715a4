"""Properties, operators and panels: thin adapters that parse, call one function, report."""
