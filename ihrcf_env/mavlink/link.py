"""The vehicle's UDP links: pymavlink connection strings in, MAVLink 2 packets out to every link.

``udpout:HOST:PORT`` sends to HOST:PORT (as PX4 SITL does to an offboard API on 14540, a ground
station on 14550) and takes the answers on the same socket; ``udpin:HOST:PORT`` (or ``udp:``)
listens on HOST:PORT and answers whoever sent. Every message is packed once and written to each
link; each received datagram is parsed on its own. :func:`check_endpoint` refuses a string that
is not one of these, a port out of range or a host that does not resolve; :meth:`Link.open`
raises :class:`LinkError` for a port in use or a destination the machine cannot reach. Received
bytes that are not MAVLink are counted and dropped.
"""

from __future__ import annotations

import select
import socket
import time
from collections.abc import Iterator, Sequence
from typing import Any

from ihrcf_env.mavlink._pymavlink import dialect, import_pymavlink

#: The connection-string schemes taken.
SCHEMES: tuple[str, ...] = ("udpout", "udpin", "udp")


class LinkError(OSError):
    """A link cannot be opened or used: the message names the connection string."""


def check_endpoint(text: str) -> tuple[str, str, int]:
    """(scheme, host, port) of a connection string ``SCHEME:HOST:PORT`` (:data:`SCHEMES`);
    ValueError naming it otherwise (the host must resolve)."""
    parts = text.split(":")
    if len(parts) != 3 or parts[0] not in SCHEMES:
        raise ValueError(f"{text!r} is not SCHEME:HOST:PORT with SCHEME one of {', '.join(SCHEMES)}")
    scheme, host, port_text = parts
    try:
        port = int(port_text)
    except ValueError:
        raise ValueError(f"{text!r}: the port {port_text!r} is not an integer") from None
    if not 1 <= port <= 65535:
        raise ValueError(f"{text!r}: the port must be in [1, 65535], got {port}")
    if not host:
        raise ValueError(f"{text!r}: no host")
    try:
        socket.getaddrinfo(host, port, socket.AF_INET, socket.SOCK_DGRAM)
    except OSError as e:
        raise ValueError(f"{text!r}: the host {host!r} does not resolve ({e.strerror or e})") from None
    return scheme, host, port


class Link:
    """The vehicle's links (module docstring), opened by :meth:`open`; close with :meth:`close`
    (also a context manager). ``bad_packets`` counts what was received and was not MAVLink."""

    def __init__(self, endpoints: Sequence[str], system_id: int = 1, component_id: int = 1) -> None:
        self.endpoints = tuple(endpoints)
        self.system_id, self.component_id = system_id, component_id
        self.connections: list[Any] = []
        self.bad_packets = 0
        self.send_errors = 0
        self.sent = 0
        m = dialect()
        self._mav = m.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self._parser = m.MAVLink(None, srcSystem=system_id, srcComponent=component_id)
        self._parser.robust_parsing = True
        self.receive_errors = 0

    def open(self) -> Link:
        """Open every link (once: a second call does nothing); :class:`LinkError` naming the first
        that fails (those opened are closed again)."""
        if self.connections:
            return self
        mavutil = import_pymavlink()
        try:
            for text in self.endpoints:
                scheme, host, port = check_endpoint(text)
                device = f"{'udpout' if scheme == 'udpout' else 'udpin'}:{host}:{port}"
                try:
                    conn = mavutil.mavlink_connection(
                        device,
                        source_system=self.system_id,
                        source_component=self.component_id,
                        dialect="common",
                        robust_parsing=True,
                    )
                except OSError as e:
                    why = "the port is in use" if e.errno == 98 else (e.strerror or str(e))
                    raise LinkError(f"cannot open {text}: {why}") from None
                self.connections.append(conn)
                if scheme == "udpout":  # an empty datagram: an unreachable destination fails here
                    try:
                        conn.port.sendto(b"", (socket.gethostbyname(host), port))
                    except OSError as e:
                        if e.errno != 111:  # refused: nobody listens yet, which is fine
                            raise LinkError(f"cannot send to {text}: {e.strerror or e}") from None
        except BaseException:
            self.close()
            raise
        return self

    def __enter__(self) -> Link:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Close every socket; safe to call twice."""
        for conn in self.connections:
            try:
                conn.close()
            except OSError:
                pass
        self.connections = []

    @property
    def closed(self) -> bool:
        return not self.connections

    def _pack(self, msg: Any) -> bytes:
        buf: bytes = msg.pack(self._mav)
        self._mav.seq = (self._mav.seq + 1) % 256
        return buf

    def send(self, msg: Any) -> None:
        """Pack ``msg`` once and write it to every link (a failed write is counted, not raised)."""
        buf = self._pack(msg)
        for conn in self.connections:
            try:
                conn.write(buf)
            except OSError:
                self.send_errors += 1
        self.sent += 1

    def wait(self, timeout: float) -> bool:
        """Wait up to ``timeout`` s for a packet on any link; True if one is there."""
        if not self.connections:
            return False
        ready, _, _ = select.select([c.port for c in self.connections], [], [], max(timeout, 0.0))
        return bool(ready)

    def receive(self) -> Iterator[Any]:
        """The messages waiting on every link, decoded. Each datagram is parsed on its own (a
        broken one cannot swallow the next); bytes that are not MAVLink are dropped and counted in
        ``bad_packets``."""
        for conn in self.connections:
            sock = conn.port
            for _ in range(10_000):  # bounded: a flood cannot hold the loop forever
                try:
                    data, addr = sock.recvfrom(65_535)
                except (BlockingIOError, InterruptedError):
                    break
                except ConnectionRefusedError:  # an ICMP answer to an earlier send: nobody listens
                    continue
                except OSError:
                    self.receive_errors += 1
                    break
                if conn.udp_server:  # answer whoever sent (pymavlink's list of a listening link)
                    conn.clients.add(addr)
                    conn.clients_last_alive[addr] = time.time()
                yield from self._parse(data)

    def _parse(self, data: bytes) -> Iterator[Any]:
        p = self._parser
        p.buf, p.buf_index, p.have_prefix_error = bytearray(), 0, False
        p.expected_length = 8  # a fresh parser's (the MAVLink 1 header and its checksum)
        try:
            msgs = p.parse_buffer(data) or []
        except Exception:  # pymavlink's parser on hostile bytes: drop the datagram, count it
            self.bad_packets += 1
            return
        if not msgs or p.buf_len() > 0:  # nothing decoded, or bytes left over
            self.bad_packets += 1
        for msg in msgs:
            if msg.get_type() in ("BAD_DATA", "UNKNOWN") or msg.get_msgId() < 0:
                self.bad_packets += 1
                continue
            yield msg


__all__ = ["SCHEMES", "Link", "LinkError", "check_endpoint"]
