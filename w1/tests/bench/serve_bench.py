#!/usr/bin/env python3
"""Figures of the live preview page under load on loopback (issue 30), for docs/watch.md:

  A. K clients holding /events open (K = 4, 8, 100): the time of GET / and GET /image.png
     (20 each, one at a time; 10 s without an answer counts as a timeout);
  B. 200 connections on / for 10 s (wrk): requests/s, latency, timeouts;
  C. 50 connections on /image.png for 10 s (wrk): requests/s, latency, resident memory;
  D. 100 clients holding /events open and 8 connections on /image.png for 10 s (wrk).

Also the page's status lines before the first pass, as a new client hears them.
    serve_bench.py SPANGLE PLUGIN_DIR REPO_DIR [SCENE [SIZE]]
SCENE defaults to assets/scenes/spheres.toml and SIZE to 320x100 (the issue's case); needs wrk
(apt-get install wrk) for B to D.
"""

import os
import re
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time


def rss_mib(pid):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024
    return 0.0


def timed_get(port, path, timeout=10.0):
    """Seconds for one GET on a new connection; None on a timeout."""
    t0 = time.perf_counter()
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=timeout) as s:
            s.sendall(f"GET {path} HTTP/1.1\r\nHost: 127.0.0.1\r\nConnection: close\r\n\r\n".encode())
            while s.recv(1 << 16):
                pass
    except (socket.timeout, ConnectionError):
        return None
    return time.perf_counter() - t0


def open_streams(port, k):
    socks = []
    for _ in range(k):
        s = socket.create_connection(("127.0.0.1", port))
        s.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
        socks.append(s)
    return socks


def drain(socks, stop):
    """Reads the streams, as browsers do, until stop is set."""
    for s in socks:
        s.setblocking(False)
    while not stop.is_set():
        for s in socks:
            try:
                s.recv(1 << 16)
            except (BlockingIOError, ConnectionError, OSError):
                pass
        time.sleep(0.02)


def wrk(url, conns, seconds=10):
    out = subprocess.run(["wrk", "-t2", f"-c{conns}", f"-d{seconds}s", "--timeout", "5s",
                          "--latency", url], capture_output=True, text=True).stdout
    rps = re.search(r"Requests/sec:\s*([\d.]+)", out)
    lat = re.search(r"Latency\s+(\S+)\s+(\S+)\s+(\S+)", out)
    p50 = re.search(r"^\s+50%\s+(\S+)", out, re.M)
    p99 = re.search(r"^\s+99%\s+(\S+)", out, re.M)
    timeouts = re.search(r"timeout (\d+)", out)
    return (f"{float(rps[1]) if rps else 0:.0f} requests/s, latency mean {lat[1] if lat else '?'} "
            f"p50 {p50[1] if p50 else '?'} p99 {p99[1] if p99 else '?'} max {lat[3] if lat else '?'}, "
            f"timeouts {timeouts[1] if timeouts else 0}")


def status_lines(port, seconds):
    """The status and pass events a client hears in its first `seconds`."""
    seen = []
    try:
        with socket.create_connection(("127.0.0.1", port), timeout=1) as s:
            s.sendall(b"GET /events HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n")
            end = time.time() + seconds
            buf = b""
            while time.time() < end:
                try:
                    b = s.recv(1 << 16)
                except socket.timeout:
                    continue
                if not b:
                    break
                buf += b
                for m in re.finditer(rb"event: (status|pass)\ndata: (.*)\n", buf):
                    line = f"{time.time() - T0:6.2f} s  {m[1].decode()}: {m[2].decode()}"
                    if line[10:] not in [x[10:] for x in seen]:
                        seen.append(line)
                buf = buf[buf.rfind(b"\n\n") + 2:] if b"\n\n" in buf else buf
                if any("pass" in x for x in seen):
                    break
    except OSError:
        pass
    return seen


T0 = time.time()


def main():
    global T0
    spangle, plugins, repo = sys.argv[1:4]
    scene = sys.argv[4] if len(sys.argv) > 4 else os.path.join(repo, "assets/scenes/spheres.toml")
    size = sys.argv[5] if len(sys.argv) > 5 else "320x100"
    tmp = tempfile.mkdtemp()
    log = os.path.join(tmp, "log.txt")
    T0 = time.time()
    proc = subprocess.Popen([spangle, "render", os.path.abspath(scene), "-o", "out.exr", "--watch",
                             "--size", size, "--serve", "0", "--plugin-path", plugins],
                            cwd=tmp, stdout=open(log, "w"), stderr=subprocess.STDOUT)
    try:
        while not re.search(r"live preview at http://127.0.0.1:(\d+)/", open(log).read()):
            time.sleep(0.02)
        port = int(re.search(r"live preview at http://127.0.0.1:(\d+)/", open(log).read())[1])
        print("before the first pass, a client heard:")
        for line in status_lines(port, 120):
            print("  " + line)
        while "watching for changes" not in open(log).read():
            time.sleep(0.1)
        print(f"first render finished {time.time() - T0:.1f} s after start; "
              f"resident memory {rss_mib(proc.pid):.1f} MiB")
        url = f"http://127.0.0.1:{port}/"
        for k in (4, 8, 100):
            socks = open_streams(port, k)
            stop = threading.Event()
            th = threading.Thread(target=drain, args=(socks, stop))
            th.start()
            time.sleep(0.5)
            for path in ("/", "/image.png"):
                ts = []
                while len(ts) < 20 and ts.count(None) < 3:  # three timeouts say enough
                    ts.append(timed_get(port, path))
                ok = [t * 1000 for t in ts if t is not None]
                print(f"A. {k} streams open, GET {path}: {len(ts) - len(ok)} of {len(ts)} timed out (10 s)"
                      + (f"; median {statistics.median(ok):.2f} ms, max {max(ok):.2f} ms" if ok else ""))
            stop.set()
            th.join()
            for s in socks:
                s.close()
            time.sleep(2)  # the old server notices closed streams within a second
        if shutil.which("wrk") is None:
            print("wrk is not installed: B to D skipped (apt-get install wrk)")
            return
        m0 = rss_mib(proc.pid)
        print(f"B. 200 connections on / for 10 s: {wrk(url, 200)}; "
              f"resident {m0:.1f} -> {rss_mib(proc.pid):.1f} MiB")
        time.sleep(1)
        m0 = rss_mib(proc.pid)
        print(f"C. 50 connections on /image.png for 10 s: {wrk(url + 'image.png', 50)}; "
              f"resident {m0:.1f} -> {rss_mib(proc.pid):.1f} MiB")
        time.sleep(1)
        socks = open_streams(port, 100)
        stop = threading.Event()
        th = threading.Thread(target=drain, args=(socks, stop))
        th.start()
        time.sleep(0.5)
        m0 = rss_mib(proc.pid)
        print(f"D. 100 streams open, 8 connections on /image.png for 10 s: "
              f"{wrk(url + 'image.png', 8)}; resident {m0:.1f} -> {rss_mib(proc.pid):.1f} MiB")
        stop.set()
        th.join()
        for s in socks:
            s.close()
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
