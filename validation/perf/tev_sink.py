"""A stand-in for tev that reads and discards: it listens on a port (default tev's, 14158, on
the loopback interface), accepts any number of connections one after another and reads
everything they send, printing each connection's byte count. For measuring what the live view
(`penumbra render --display-server HOST:PORT`) costs a render without tev's own drawing:

    python3 validation/perf/tev_sink.py 14158 &
    penumbra render scenes/cornell-box.xml -D res=512 --spp 32 --display-server localhost:14158

Standard library only; stops on Ctrl-C or SIGTERM.
"""

import signal
import socket
import sys


def main() -> None:
    port = int(sys.argv[1]) if len(sys.argv) > 1 else 14158
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
    server.bind(("127.0.0.1", port))
    server.listen(4)
    print(f"listening on 127.0.0.1:{port}", file=sys.stderr, flush=True)
    buf = bytearray(1 << 20)
    try:
        while True:
            conn, peer = server.accept()
            total = 0
            with conn:
                while n := conn.recv_into(buf):
                    total += n
            print(f"{peer[0]}:{peer[1]}: {total} bytes", file=sys.stderr, flush=True)
    except KeyboardInterrupt:
        pass


if __name__ == "__main__":
    main()
