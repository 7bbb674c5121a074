"""The run loop: stepping an engine, recording, the outcome, compiling ahead, profiling."""
