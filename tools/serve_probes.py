#!/usr/bin/env python3
"""Probes `uwnr serve` as an attacker and a careless client would, and prints what it saw.

    python3 tools/serve_probes.py [--bin target/release/uwnr] [--memory-mb N]

Starts the binary on the bundled samples (a free port, a temporary folder), then:
- slow clients: 70 connections sending their request head a byte a second; the time a normal
  client waits for `/api/info` meanwhile;
- worst-case uploads: 8 concurrent uploads of an all-zero 8192x2929 PNG (70 kB, 24 megapixels);
  their statuses and the server's peak RSS (VmHWM);
- DNS rebinding and cross-site requests: `Host: evil.example`, a `text/plain` POST with another
  Origin;
- HTTP: HEAD, a wrong method on a known path, conflicting Content-Length, a chunked body;
- with `--big-refs`, a second server on nine 6000x4000 references: a preview render with each
  (Reinhard keeps the decoded reference), then the server's resident memory (VmRSS) and peak.
Linux only (reads /proc). Needs Pillow and NumPy for the PNG.
"""

import argparse
import io
import json
import os
import socket
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def start(binary, tmp, extra):
    clean, refs = Path(tmp, "clean"), Path(tmp, "refs")
    clean.mkdir()
    refs.mkdir()
    for n in ["clean-room.jpg", "clean-statues.jpg"]:
        (clean / n).write_bytes((ROOT / "assets" / "samples" / n).read_bytes())
    for n in ["ref-blue.jpg", "ref-green.png"]:
        (refs / n).write_bytes((ROOT / "assets" / "samples" / n).read_bytes())
    p = subprocess.Popen(
        [binary, "serve", "--clean", str(clean), "--references", str(refs), "--port", "0", *extra],
        stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    line = p.stdout.readline().strip()
    host, port = line.split("http://")[1].split("/")[0].rsplit(":", 1)
    return p, (host, int(port))


def send(addr, data, timeout=60):
    s = socket.create_connection(addr, timeout=timeout)
    s.sendall(data)
    out = b""
    try:
        while True:
            b = s.recv(65536)
            if not b:
                break
            out += b
    except OSError:
        pass
    s.close()
    head, _, body = out.partition(b"\r\n\r\n")
    status = int(head[9:12]) if len(head) >= 12 and head[9:12].isdigit() else 0
    return status, head.decode("latin1").lower(), body


def req(addr, method, path, body=b"", headers=()):
    lines = [f"{method} {path} HTTP/1.1", "Host: 127.0.0.1", f"Content-Length: {len(body)}",
             "Connection: close", *headers, "", ""]
    return send(addr, "\r\n".join(lines).encode() + body)


def vm_hwm_mb(pid):
    for line in open(f"/proc/{pid}/status"):
        if line.startswith("VmHWM:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def slow_clients(addr, n=70):
    stop = threading.Event()

    def dawdle():
        try:
            s = socket.create_connection(addr, timeout=60)
            for b in b"GET /api/info HTTP/1.1\r\nHost: 127.0.0.1\r\n\r\n":
                if stop.is_set():
                    break
                s.sendall(bytes([b]))
                time.sleep(1)
            s.close()
        except OSError:
            pass

    threads = [threading.Thread(target=dawdle, daemon=True) for _ in range(n)]
    for t in threads:
        t.start()
    time.sleep(3)
    t0 = time.time()
    status, _, _ = req(addr, "GET", "/api/info")
    waited = time.time() - t0
    stop.set()
    return status, waited


def zero_png():
    import numpy as np
    from PIL import Image
    buf = io.BytesIO()
    Image.fromarray(np.zeros((2929, 8192, 3), np.uint8)).save(buf, "PNG")
    return buf.getvalue()


def uploads(addr, pid, png, n=8):
    results = [None] * n

    def up(i):
        results[i] = req(addr, "POST", f"/api/upload?kind=clean&name=z{i}.png", png)[0]

    threads = [threading.Thread(target=up, args=(i,)) for i in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return results, vm_hwm_mb(pid)


def big_references(binary, extra):
    import numpy as np
    from PIL import Image
    with tempfile.TemporaryDirectory() as tmp:
        p, addr = start(binary, tmp, extra)
        p.terminate()
        p.wait()
        refs = Path(tmp, "refs")
        y, x = np.mgrid[0:4000, 0:6000]
        for i in range(9):
            img = np.stack([(x * (i + 1)) % 256, y % 256, (x + y) % 256], -1).astype(np.uint8)
            Image.fromarray(img).save(refs / f"big{i}.jpg", quality=80)
        clean = Path(tmp, "clean")
        cmd = [binary, "serve", "--clean", str(clean), "--references", str(refs), "--port", "0",
               *extra]
        p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        line = p.stdout.readline().strip()
        host, port = line.split("http://")[1].split("/")[0].rsplit(":", 1)
        addr = (host, int(port))
        try:
            for i in range(9):
                body = json.dumps({"view": f"big|{i}", "clean": {"index": 0}, "reference": i,
                                   "options": {"method": "reinhard"}}).encode()
                st, _, b = req(addr, "POST", "/api/render", body)
                job = json.loads(b)["job"]
                while True:
                    _, _, b = req(addr, "GET", f"/api/job/{job}")
                    if json.loads(b)["state"] not in ("queued", "running"):
                        break
                    time.sleep(0.2)
            rss = [l for l in open(f"/proc/{p.pid}/status") if l.startswith("VmRSS:")][0]
            print(f"9 renders with 6000x4000 references: VmRSS {int(rss.split()[1]) / 1024:.0f} MB"
                  f" after, peak {vm_hwm_mb(p.pid):.0f} MB")
        finally:
            p.terminate()
            p.wait()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--bin", default=str(ROOT / "target" / "release" / "uwnr"))
    ap.add_argument("--memory-mb", default=None)
    ap.add_argument("--big-refs", action="store_true")
    a = ap.parse_args()
    extra = ["--memory-mb", a.memory_mb] if a.memory_mb else []
    png = zero_png()
    with tempfile.TemporaryDirectory() as tmp:
        p, addr = start(a.bin, tmp, extra)
        try:
            idle = vm_hwm_mb(p.pid)
            status, waited = slow_clients(addr)
            print(f"70 slow clients: a normal client got {status} after {waited:.2f} s")
            statuses, peak = uploads(addr, p.pid, png)
            print(f"8 worst-case uploads ({len(png)} bytes each): statuses {statuses}, "
                  f"peak RSS {peak:.0f} MB (idle {idle:.0f} MB)")
            rebound = send(addr, b"GET /api/info HTTP/1.1\r\nHost: evil.example\r\n"
                                 b"Connection: close\r\n\r\n")[0]
            print("Host: evil.example ->", rebound)
            body = json.dumps({"view": "x", "clean": {"index": 0}, "reference": 0,
                               "options": {"method": "reinhard"}}).encode()
            print("cross-origin text/plain POST ->", req(
                addr, "POST", "/api/render", body,
                ["Origin: http://evil.example", "Content-Type: text/plain"])[0])
            st, head, b = req(addr, "HEAD", "/api/info")
            print(f"HEAD -> {st}, {len(b)} body bytes")
            st, head, _ = req(addr, "DELETE", "/api/info")
            allow = [l for l in head.split("\r\n") if l.startswith("allow:")]
            print(f"DELETE /api/info -> {st} {allow}")
            print("conflicting Content-Length ->", send(
                addr, b"POST /api/render HTTP/1.1\r\nHost: 127.0.0.1\r\nContent-Length: 5\r\n"
                      b"Content-Length: 7\r\n\r\n{}{}{}{")[0])
            chunk = b"%x\r\n%s\r\n0\r\n\r\n" % (len(body), body)
            print("chunked render request ->", send(
                addr, b"POST /api/render HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                      b"Transfer-Encoding: chunked\r\nConnection: close\r\n\r\n" + chunk)[0])
        finally:
            p.terminate()
            p.wait()
    if a.big_refs:
        big_references(a.bin, extra)
    return 0


if __name__ == "__main__":
    sys.exit(main())
