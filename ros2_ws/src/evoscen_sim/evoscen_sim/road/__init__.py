"""The road: the OpenDRIVE reader, the vectorised road model built on it and its compiled queries.
May import the ground floor, the configuration, the share files and the contract."""
