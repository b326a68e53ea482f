"""A packet capture on the loopback interface, for the test that payloads are encrypted on the wire.

A raw ``AF_PACKET`` socket on ``lo`` (root, or CAP_NET_RAW: no tcpdump or scapy needed) keeps the UDP
payloads sent to the ports of one DDS domain (ROS 2's port mapping: ``7400 + 250 d`` .. ``+ 249``), so
runs of other domains on the same machine never count. :meth:`LoopbackCapture.find` says which of some
byte patterns (the doubles of known states and commands) appear in them.
"""
import socket
import struct
import threading

ETH_P_ALL = 0x0003
#: Kernel buffer of the capture socket: a lockstep team writes a few MB/s on loopback, and the reading
#: thread may wait for the CPU on a loaded machine; root may raise the buffer past rmem_max (SO_RCVBUFFORCE).
BUFFER_BYTES = 64 << 20
SO_RCVBUFFORCE = 33


def can_capture() -> str | None:
    """Return None if a raw socket on ``lo`` can be opened here, else why not."""
    try:
        socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL)).close()
    except (OSError, AttributeError) as exc:
        return f'no raw socket on loopback ({exc}): needs Linux and root or CAP_NET_RAW'
    return None


class LoopbackCapture:
    """Capture the UDP payloads to DDS domain ``domain`` on ``lo`` from :meth:`start` to :meth:`stop`."""

    def __init__(self, domain: int):
        self.lo, self.hi = 7400 + 250 * domain, 7400 + 250 * domain + 249
        self.payloads = []
        self._sock = socket.socket(socket.AF_PACKET, socket.SOCK_RAW, socket.htons(ETH_P_ALL))
        try:
            self._sock.setsockopt(socket.SOL_SOCKET, SO_RCVBUFFORCE, BUFFER_BYTES)
        except OSError:
            self._sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, BUFFER_BYTES)
        self._sock.bind(('lo', 0))
        self._sock.settimeout(0.2)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        while not self._stop.is_set():
            try:
                frame, address = self._sock.recvfrom(1 << 16)
            except TimeoutError:
                continue
            if address[2] == socket.PACKET_OUTGOING:   # lo shows every packet twice: keep the incoming copy
                continue
            payload = self._udp_payload(frame)
            if payload is not None:
                self.payloads.append(payload)

    def _udp_payload(self, frame: bytes) -> bytes | None:
        """Return the UDP payload of an IPv4 frame to a port of the domain (None for anything else)."""
        if len(frame) < 42 or frame[12:14] != b'\x08\x00' or frame[23] != 17:
            return None
        ihl = (frame[14] & 0x0F) * 4
        udp = 14 + ihl
        dport = struct.unpack_from('!H', frame, udp + 2)[0]
        return frame[udp + 8:] if self.lo <= dport <= self.hi else None

    def start(self) -> 'LoopbackCapture':
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()
        self._sock.close()

    def user_data_bytes(self) -> int:
        """Bytes of the RTPS messages captured (every payload to the domain's ports)."""
        return sum(len(p) for p in self.payloads)

    def find(self, patterns) -> set:
        """Return those of the byte strings ``patterns`` that occur in some captured payload."""
        blob = b'\x00'.join(self.payloads)
        return {p for p in patterns if p in blob}


def doubles(values) -> list:
    """Return the distinct little-endian IEEE 754 doubles of ``values`` (CDR ``float64`` on x86)."""
    return sorted({struct.pack('<d', float(v)) for v in values})


__all__ = ['LoopbackCapture', 'can_capture', 'doubles']
