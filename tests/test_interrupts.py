"""A Ctrl-C held back until the code says where it may stop (cagekit.interrupts)."""

import os
import signal
import threading
import time

import pytest

from cagekit.interrupts import sigint_deferred


def test_a_ctrl_c_is_raised_only_where_the_code_asks_and_once():
    with sigint_deferred() as pending:
        os.kill(os.getpid(), signal.SIGINT)
        os.kill(os.getpid(), signal.SIGINT)  # two before a call count as one
        for _ in range(100_000):  # no KeyboardInterrupt in these bytecodes
            pass
        with pytest.raises(KeyboardInterrupt):
            pending()
        pending()  # raised once
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_ctrl_c_after_the_last_call_is_raised_as_the_block_ends():
    with pytest.raises(KeyboardInterrupt):
        with sigint_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_ctrl_c_wins_over_an_error_on_its_way_out():
    with pytest.raises(KeyboardInterrupt) as caught:
        with sigint_deferred():
            os.kill(os.getpid(), signal.SIGINT)
            time.sleep(0.01)
            raise ValueError("the block's own error")
    assert isinstance(caught.value.__context__, ValueError)
    assert signal.getsignal(signal.SIGINT) is signal.default_int_handler


def test_a_handler_set_in_the_block_is_kept():
    def mine(signum, frame):
        raise RuntimeError("mine")

    previous = signal.getsignal(signal.SIGINT)
    try:
        with sigint_deferred():
            signal.signal(signal.SIGINT, mine)
        assert signal.getsignal(signal.SIGINT) is mine
    finally:
        signal.signal(signal.SIGINT, previous)


def test_nothing_is_deferred_outside_the_main_thread_or_where_sigint_is_ignored():
    handlers = []

    def in_thread():
        with sigint_deferred():
            handlers.append(signal.getsignal(signal.SIGINT))

    thread = threading.Thread(target=in_thread)
    thread.start()
    thread.join()
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        with sigint_deferred() as pending:
            handlers.append(signal.getsignal(signal.SIGINT))
            os.kill(os.getpid(), signal.SIGINT)  # ignored, as before
            time.sleep(0.01)
            pending()
    finally:
        signal.signal(signal.SIGINT, previous)
    assert handlers == [signal.default_int_handler, signal.SIG_IGN]
