"""Unit tests: functions and classes in this process, on inputs whose answers are known."""
