"""``swarm host`` processes on this machine (loopback) for the tests of runs
placed on hosts: their logins, folders and logs, and the agents they fork."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from formation_swarm.launch.launcher import free_port

PY = [sys.executable, "-m", "formation_swarm.cli"]


class Hosts:
    """``swarm host`` processes on this machine, each with its login and folder
    (with ``tls``, a folder of :func:`make_tls`'s files: over TLS)."""

    def __init__(self, tmp_path: Path, names: list[str], tls: Path | None = None) -> None:
        self.tmp = tmp_path
        self.tls = tls
        self.endpoint = f"{'tcp' if tls is None else 'tls'}/127.0.0.1:{free_port()}"
        ca = [] if tls is None else ["--tls-ca", str(tls / "ca.pem")]
        made = subprocess.run(
            [*PY, "secure", "--hosts", ",".join(names), "--out", str(tmp_path / "sec"), *ca],
            capture_output=True,
            text=True,
            timeout=60,
            check=False,
        )
        assert made.returncode == 0, made.stderr
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        for n in names:
            self.start(n)

    def start(self, n: str) -> None:
        """Host ``n``'s process (again, after it was stopped: its log goes on)."""
        with open(self.tmp / f"host-{n}.log", "ab") as log:
            self.procs[n] = subprocess.Popen(
                [
                    *PY,
                    "host",
                    "--connect",
                    self.endpoint,
                    "--name",
                    n,
                    "--auth",
                    str(self.tmp / "sec" / f"host-{n}.json"),
                    "--workdir",
                    str(self.tmp / f"work-{n}"),
                ],
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
            )

    def run_argv(self, out: Path, names: str) -> list[str]:
        return [
            *PY,
            "run",
            "fig11_obstacles",
            "--seed",
            "5",
            "--out",
            str(out),
            "--hosts",
            names,
            "--listen",
            self.endpoint,
            "--host-logins",
            str(self.tmp / "sec" / "hosts.txt"),
            *([] if self.tls is None else [f"--tls-{n}={self.tls / f}" for n, f in TLS_FILES.items()]),
        ]

    def log(self, name: str) -> str:
        return (self.tmp / f"host-{name}.log").read_text()

    def close(self) -> None:
        for p in self.procs.values():
            if p.poll() is None:
                p.terminate()
        for p in self.procs.values():
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()


TLS_FILES = {"ca": "ca.pem", "cert": "router.pem", "key": "router.key"}  # swarm run's --tls-NAME: make_tls's


def make_tls(folder: Path) -> Path:
    """A CA and the router's certificate for 127.0.0.1 and key, in ``folder``
    (the guide's openssl commands, deploy/README.md "Steps")."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "ext.cnf").write_text("subjectAltName=IP:127.0.0.1\n")
    ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"]
    sign = ["-CA", "ca.pem", "-CAkey", "ca.key", "-CAcreateserial", "-days", "1", "-extfile", "ext.cnf"]
    for argv in (
        ["req", "-x509", *ec, "-keyout", "ca.key", "-out", "ca.pem", "-days", "1", "-subj", "/CN=swarm test CA"],
        ["req", *ec, "-keyout", "router.key", "-out", "router.csr", "-subj", "/CN=router"],
        ["x509", "-req", "-in", "router.csr", "-out", "router.pem", *sign],
    ):
        subprocess.run(["openssl", *argv], cwd=folder, check=True, capture_output=True, timeout=30)
    return folder


def summary_placement(out: Path) -> dict[str, str]:
    return json.loads((out / "summary.json").read_text())["placement"]


def parents() -> dict[int, int]:
    out = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                out[int(entry.name)] = int((entry / "stat").read_text().rsplit(")", 1)[1].split()[1])
            except (OSError, IndexError, ValueError):
                continue
    return out


def agents_of(host_pid: int) -> list[int]:
    """The processes a host forked (through its spawner's fork server): its agents."""
    forks = parents()
    servers = {p for p, pp in forks.items() if pp == host_pid}
    return sorted(p for p, pp in forks.items() if pp in servers)


def alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return False
    return state != "Z"
