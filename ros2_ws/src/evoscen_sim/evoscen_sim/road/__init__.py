"""The road: the OpenDRIVE reader, the vectorised road model built on it and its compiled queries."""
