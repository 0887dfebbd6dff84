"""Records what tev's own Python client, `tevclient`, sends for one open, create, update and
close, as the independent truth for penumbra's tev protocol (`tests/tev_protocol.rs` sends the
same four commands with penumbra's `io::tev` and compares the bytes).

    python3 -m venv .venv && .venv/bin/pip install -r tests/data/tev/requirements.txt
    .venv/bin/python tests/data/tev/record.py      # writes tests/data/tev/tevclient-stream.bin.gz

tevclient talks to a listening socket (here one on the loopback interface that keeps every
byte it receives), through its socket client `tevclient.Ipc`, exactly as it would talk to tev.
The commands and the image's values are the ones `tests/tev_protocol.rs` writes out; change
both together.
"""

import gzip
import pathlib
import socket
import threading

import numpy as np
import tevclient

HERE = pathlib.Path(__file__).resolve().parent
OUT = HERE / "tevclient-stream.bin.gz"

# The image: 130 x 129 pixels (four blocks of tevclient's 128 x 128, two of them partial),
# the six channels a live view with --variance sends, values
# v(x, y, c) = ((31 x + 17 y + 7 c) mod 97) / 7 - 3, rounded to float32.
WIDTH, HEIGHT = 130, 129
NAME = "cornell-box seed 7"
CHANNELS = ["R", "G", "B", "rel_error.R", "rel_error.G", "rel_error.B"]
OPEN_PATH = "renders/cornell-box.exr"


def image() -> np.ndarray:
    y, x, c = np.meshgrid(np.arange(HEIGHT), np.arange(WIDTH), np.arange(len(CHANNELS)), indexing="ij")
    return (((31 * x + 17 * y + 7 * c) % 97) / 7.0 - 3.0).astype(np.float32)


def main() -> None:
    server = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    server.bind(("127.0.0.1", 0))
    server.listen(1)
    received = bytearray()

    def receive() -> None:
        conn, _ = server.accept()
        with conn:
            while chunk := conn.recv(1 << 16):
                received.extend(chunk)

    listener = threading.Thread(target=receive)
    listener.start()
    with tevclient.Ipc("127.0.0.1", server.getsockname()[1]) as tev:
        tev.open_image(OPEN_PATH, channel_selector="", grab_focus=True)
        tev.create_image(NAME, WIDTH, HEIGHT, channel_names=CHANNELS, grab_focus=True)
        tev.update_image(NAME, image(), channel_names=CHANNELS, grab_focus=False)
        tev.close_image(NAME)
    listener.join()
    server.close()
    with open(OUT, "wb") as f, gzip.GzipFile(fileobj=f, mode="wb", mtime=0, filename="") as gz:
        gz.write(bytes(received))
    print(f"tevclient {tevclient.__version__}: {len(received)} bytes -> {OUT}")


if __name__ == "__main__":
    main()
