"""Waiting with a deadline, for the demo and the tests: poll a condition instead of sleeping."""
import time


def wait_until(condition, timeout, message, interval=0.05):
    """Poll `condition` until it returns a truthy value, and return that value.

    After `timeout` s raises TimeoutError with `message`, which may be a function,
    called only on failure to describe the state then.
    """
    deadline = time.monotonic() + timeout
    while True:
        value = condition()
        if value:
            return value
        if time.monotonic() > deadline:
            text = message() if callable(message) else message
            raise TimeoutError(f"{text} (waited {timeout:.1f} s)")
        time.sleep(interval)
