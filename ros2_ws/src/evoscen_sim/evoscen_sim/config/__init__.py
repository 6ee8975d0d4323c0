"""The configuration: the scenario configuration, its schema, checkers and loader, and the input limits.
May import the ground floor (``errors``, ``limits``), the model registry and share files, and the contract."""
