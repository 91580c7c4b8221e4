"""The controllers themselves (UMC, E-UMC, PEC and the recording mode), each one
module that owns its decision; the registry of their names and capabilities, the
factory that builds one by name and the `ControllerSpec` the server sends the worker."""
