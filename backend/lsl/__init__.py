"""What every LSL stream of the server shares: stream names as the experimenter types
them and the resolver query built from them, liblsl's exceptions, and the reconnection
backoff. Below the lab's marker inlets and outlets, the EMG inlets and the request
models that validate a name; it imports nothing of the project."""
