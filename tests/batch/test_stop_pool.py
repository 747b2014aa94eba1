"""``_stop_pool`` ends a pool whose worker is stopped in the middle of sending a result.

A worker killed while it writes a result larger than a pipe holds left the pool's manager
thread waiting in ``recv`` for the rest of the message; Python joins that thread at exit,
so ``cagekit amplify`` printed "interrupted" and never ended (CI met it once). The script
below puts a worker in exactly that state, deterministically: it writes the header of a
10 MB message on the pool's result pipe and waits, then the parent stops the pool and
exits.
"""

import subprocess
import sys
import textwrap

#: the parent must end within this many seconds (it ends in about one when stopped right)
PATIENCE = 60

HALF_SENT = textwrap.dedent("""
    import gc, multiprocessing, multiprocessing.queues, os, struct, sys, time
    from cagekit.batch.amplify import _stop_pool, process_pool

    def send_half(marker):
        results = [queue for queue in gc.get_objects()
                   if isinstance(queue, multiprocessing.queues.SimpleQueue)]
        header = struct.pack("!i", 10_000_000)  # a 10 MB message, of which nothing follows
        for queue in results:
            queue._writer._send(header)
        open(marker, "w").close()
        time.sleep(600)

    if __name__ == "__main__":
        marker = sys.argv[1]
        pool = process_pool(1)
        pool.submit(send_half, marker)
        while not os.path.exists(marker):
            time.sleep(0.05)
        time.sleep(0.5)  # the manager thread is in recv, waiting for the rest
        _stop_pool(pool)
        print("stopped", flush=True)
""")


def test_a_pool_stopped_while_a_worker_sends_its_result_lets_the_process_end(tmp_path):
    script = tmp_path / "half_sent.py"
    script.write_text(HALF_SENT)
    try:
        done = subprocess.run([sys.executable, str(script), str(tmp_path / "sending")],
                              capture_output=True, text=True, timeout=PATIENCE)
    except subprocess.TimeoutExpired as hung:
        raise AssertionError(f"the process did not end: {hung.stdout!r}") from None
    assert done.stdout == "stopped\n", done.stderr
    assert done.returncode == 0 and done.stderr == "", done.stderr  # nothing ignored at exit
