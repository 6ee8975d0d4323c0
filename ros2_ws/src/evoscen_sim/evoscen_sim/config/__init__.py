"""The configuration: the scenario configuration, its schema, checkers and loader, and the input limits."""
