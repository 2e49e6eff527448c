"""User studies with people: protocols, trial sequences, participant and experimenter pages, session data."""
