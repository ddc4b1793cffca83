"""The DoE on a TLS-secured Dask cluster, as docs/mission.md shows it.

Dask's protocol unpickles what the other side sends: a cluster reachable by others must
authenticate both ends. A certificate authority, a scheduler certificate and a client
certificate are made here (``cryptography``); the scheduler and a worker are started
with Dask's ``--tls-*`` options on 127.0.0.1, and ``ovtraj run --runner dask`` reaches
the scheduler named by ``OVTRAJ_DASK_ADDRESS`` (``tls://``) with the client certificate
from Dask's standard environment variables. A client without a certificate is refused,
one line, exit 2, the store untouched.
"""

from __future__ import annotations

import datetime
import ipaddress
import subprocess
from pathlib import Path

import pytest

from ovtraj.runs import RunStore
from tests.test_dask_cluster import (
    DASK,
    OVTRAJ,
    RUN_TIMEOUT_S,
    Cluster,
    _config,
    _environment,
    _stored_in,
)

# Left out of the fast tier (-m "not slow"): it starts a TLS-secured Dask cluster.
pytestmark = pytest.mark.slow

_TLS_ENV = "DASK_DISTRIBUTED__COMM__TLS__"


def _certificates(folder: Path) -> dict[str, Path]:
    """A CA and two certificates it signs (the scheduler's and worker's, the client's),
    valid for 127.0.0.1, as PEM files."""
    from cryptography import x509
    from cryptography.hazmat.primitives import hashes, serialization
    from cryptography.hazmat.primitives.asymmetric import ec
    from cryptography.x509.oid import NameOID

    now = datetime.datetime.now(datetime.UTC)
    ca_key = ec.generate_private_key(ec.SECP256R1())
    ca_name = x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, "ovtraj test CA")])
    ca = (
        x509.CertificateBuilder()
        .subject_name(ca_name)
        .issuer_name(ca_name)
        .public_key(ca_key.public_key())
        .serial_number(x509.random_serial_number())
        .not_valid_before(now - datetime.timedelta(minutes=5))
        .not_valid_after(now + datetime.timedelta(days=1))
        .add_extension(x509.BasicConstraints(ca=True, path_length=None), critical=True)
        .sign(ca_key, hashes.SHA256())
    )
    files = {"ca": folder / "ca.pem"}
    files["ca"].write_bytes(ca.public_bytes(serialization.Encoding.PEM))
    for name in ("cluster", "client"):
        key = ec.generate_private_key(ec.SECP256R1())
        cert = (
            x509.CertificateBuilder()
            .subject_name(x509.Name([x509.NameAttribute(NameOID.COMMON_NAME, name)]))
            .issuer_name(ca_name)
            .public_key(key.public_key())
            .serial_number(x509.random_serial_number())
            .not_valid_before(now - datetime.timedelta(minutes=5))
            .not_valid_after(now + datetime.timedelta(days=1))
            .add_extension(
                x509.SubjectAlternativeName([x509.IPAddress(ipaddress.ip_address("127.0.0.1"))]),
                critical=False,
            )
            .sign(ca_key, hashes.SHA256())
        )
        files[f"{name}-cert"] = folder / f"{name}.pem"
        files[f"{name}-key"] = folder / f"{name}-key.pem"
        files[f"{name}-cert"].write_bytes(cert.public_bytes(serialization.Encoding.PEM))
        files[f"{name}-key"].write_bytes(
            key.private_bytes(
                serialization.Encoding.PEM,
                serialization.PrivateFormat.PKCS8,
                serialization.NoEncryption(),
            )
        )
    return files


class TlsCluster(Cluster):
    """The module's cluster, spoken to over TLS."""

    def __init__(self, root: Path) -> None:
        super().__init__(root)
        self.address = f"tls://127.0.0.1:{self.port}"
        self.files = _certificates(root)

    def tls_options(self) -> list[str]:
        return [
            "--tls-ca-file",
            str(self.files["ca"]),
            "--tls-cert",
            str(self.files["cluster-cert"]),
            "--tls-key",
            str(self.files["cluster-key"]),
        ]

    def worker(self, name: str, python: Path | None = None) -> subprocess.Popen:
        command = [str(DASK), "worker", self.address, *self.tls_options()]
        return self.start(name, [*command, "--nthreads", "1", "--name", name, "--no-dashboard"])

    def client_environment(self) -> dict[str, str]:
        """Dask's own configuration of a client's TLS (what docs/mission.md shows)."""
        return {
            f"{_TLS_ENV}CA_FILE": str(self.files["ca"]),
            f"{_TLS_ENV}CLIENT__CERT": str(self.files["client-cert"]),
            f"{_TLS_ENV}CLIENT__KEY": str(self.files["client-key"]),
            "DASK_DISTRIBUTED__COMM__REQUIRE_ENCRYPTION": "True",
        }

    def workers(self) -> int:
        from distributed import Client
        from distributed.security import Security

        security = Security(
            tls_ca_file=str(self.files["ca"]),
            tls_client_cert=str(self.files["client-cert"]),
            tls_client_key=str(self.files["client-key"]),
            require_encryption=True,
        )
        with Client(self.address, security=security, timeout=30) as client:
            return len(client.scheduler_info(n_workers=-1)["workers"])


@pytest.fixture(scope="module")
def tls_cluster(tmp_path_factory):
    cluster = TlsCluster(tmp_path_factory.mktemp("dask-tls"))
    try:
        cluster.start(
            "scheduler",
            [
                str(DASK),
                "scheduler",
                "--host",
                "127.0.0.1",
                "--port",
                str(cluster.port),
                "--protocol",
                "tls",
                *cluster.tls_options(),
                "--no-dashboard",
            ],
        )
        cluster.worker("worker-1")
        cluster.wait_for_workers(1)
        yield cluster
    finally:
        cluster.stop()


def _ovtraj_run(config: Path, env: dict[str, str]) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(OVTRAJ), "run", str(config), "--runner", "dask"],
        cwd=config.parent,
        env=env,
        capture_output=True,
        text=True,
        timeout=RUN_TIMEOUT_S,
    )


def test_the_doe_runs_on_a_tls_cluster_named_by_the_environment(tls_cluster, tmp_path):
    config = _config(tmp_path / "project", samples=2, batch_size=1)
    env = _environment() | {"OVTRAJ_DASK_ADDRESS": tls_cluster.address}
    # Without the client certificate: refused by the scheduler, one line, nothing stored.
    refused = _ovtraj_run(config, env)
    assert refused.returncode == 2, refused.stdout + refused.stderr
    assert "Traceback" not in refused.stderr and len(refused.stderr.strip().splitlines()) == 1
    assert tls_cluster.address in refused.stderr
    # With it, from Dask's environment variables: every sample stored.
    done = _ovtraj_run(config, env | tls_cluster.client_environment())
    assert done.returncode == 0, done.stdout + done.stderr
    stored = _stored_in(done.stdout)
    run = RunStore(stored.parent).run(stored.name)
    assert run.manifest["status"] == "complete" and list(run.totals()["sample_id"]) == [0, 1]
    assert run.verify().clean
    assert "batch 1/2" in done.stdout and "batch 2/2" in done.stdout
    assert "Traceback" not in tls_cluster.log("worker-1")
