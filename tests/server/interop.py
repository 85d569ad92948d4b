#!/usr/bin/python3
"""Python interop test of probebake.v1 (docs/service.md), run by ctest with Debian's /usr/bin/python3.

Starts a server on a free loopback port with its own data folder and a token, then, as a
Python gRPC client with stubs generated from the .proto files at build time: checks health
(grpc.health.v1) and reflection (grpc.reflection.v1alpha), refuses a call without the token,
uploads a mesh as a blob in chunks, submits a job read from proto3 JSON (the job file format)
that references the blob, watches it to SUCCEEDED, reads the volume back by digest in pieces
and checks its SHA-256, and, with --expect-vdb, opens it with pyopenvdb.

Usage: interop.py --server-bin PATH --stubs DIR [--expect-vdb] [--server-arg ARG ...]
"""

import argparse
import hashlib
import os
import signal
import subprocess
import sys
import tempfile
import time


def fail(message):
    print("FAIL: " + message, file=sys.stderr)
    sys.exit(1)


def check(condition, message):
    if not condition:
        fail(message)


FLOOR_OBJ = b"""# a 10 x 10 floor at z = 0, facing +z
v -5 -5 0
v 5 -5 0
v 5 5 0
v -5 5 0
f 1 2 3
f 1 3 4
"""

JOB_JSON = """{
  "scene": {
    "materials": [{"name": "white", "albedo": [0.5, 0.5, 0.5]}],
    "meshes": [{"name": "floor", "blob": {"hash": "%s", "sizeBytes": "%d"}, "format": "obj",
                "material": "white"}],
    "lights": [{"point": {"position": [0, 0, 3], "intensity": [10, 10, 10]}}]
  },
  "grid": {"min": [-1, -1, 1], "max": [1, 1, 1], "counts": [3, 3, 1], "placement": "ALL"},
  "settings": {"shOrder": 1, "samplesPerProbe": 16, "maxDepth": 2, "seed": 3}
}"""


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--server-bin", required=True)
    parser.add_argument("--stubs", required=True)
    parser.add_argument("--expect-vdb", action="store_true")
    parser.add_argument("--server-arg", action="append", default=[])
    args = parser.parse_args()

    sys.path.insert(0, args.stubs)
    import grpc
    from google.protobuf import json_format
    from probebake.v1 import job_pb2, service_pb2, service_pb2_grpc

    with tempfile.TemporaryDirectory(prefix="probebake_interop_") as tmp:
        token = "interop-token-42"
        token_file = os.path.join(tmp, "token")
        with open(token_file, "w") as f:
            f.write(token + "\n")
        port_file = os.path.join(tmp, "port")
        log = open(os.path.join(tmp, "server.log"), "w")
        server = subprocess.Popen(
            [args.server_bin, "--listen", "127.0.0.1:0", "--data-dir", os.path.join(tmp, "data"),
             "--port-file", port_file, "--token-file", token_file] + args.server_arg,
            stdout=log, stderr=subprocess.STDOUT)
        try:
            run(args, grpc, json_format, job_pb2, service_pb2, service_pb2_grpc, port_file, token)
        except BaseException:
            log.flush()
            with open(os.path.join(tmp, "server.log")) as f:
                print(f.read(), file=sys.stderr)
            raise
        finally:
            server.send_signal(signal.SIGTERM)
            try:
                code = server.wait(timeout=20)
            except subprocess.TimeoutExpired:
                server.kill()
                code = "timeout"
            log.close()
        check(code == 0, "server exit code after SIGTERM: %s" % code)
    print("interop: OK")


def run(args, grpc, json_format, job_pb2, service_pb2, service_pb2_grpc, port_file, token):
    deadline = time.time() + 30
    while not (os.path.exists(port_file) and open(port_file).read().endswith("\n")):
        check(time.time() < deadline, "server did not write its port")
        time.sleep(0.02)
    port = int(open(port_file).read())
    channel = grpc.insecure_channel("127.0.0.1:%d" % port)
    grpc.channel_ready_future(channel).result(timeout=10)
    auth = [("authorization", "Bearer " + token)]

    # Health: grpc.health.v1.Health/Check {service: ""} is empty bytes; SERVING is field 1 = 1.
    health = channel.unary_unary("/grpc.health.v1.Health/Check",
                                 request_serializer=lambda b: b, response_deserializer=lambda b: b)
    check(health(b"", timeout=5) == b"\x08\x01", "health is not SERVING")

    # Reflection (v1alpha): list_services (field 7, empty string) names our services.
    reflection = channel.stream_stream(
        "/grpc.reflection.v1alpha.ServerReflection/ServerReflectionInfo",
        request_serializer=lambda b: b, response_deserializer=lambda b: b)
    replies = list(reflection(iter([b"\x3a\x00"]), metadata=auth, timeout=5))
    check(len(replies) == 1 and b"probebake.v1.BakeJobs" in replies[0]
          and b"probebake.v1.ContentStorage" in replies[0],
          "reflection did not list the probebake services: %r" % replies)
    # Without the token reflection is refused too (cancelled by the server's interceptor: a
    # gRPC server interceptor cannot choose the status code).
    try:
        replies = list(reflection(iter([b"\x3a\x00"]), timeout=5))
        fail("reflection answered without a token: %r" % replies)
    except grpc.RpcError as e:
        check(e.code() in (grpc.StatusCode.CANCELLED, grpc.StatusCode.UNAUTHENTICATED),
              "reflection without a token: %s" % e.code())

    caps_stub = service_pb2_grpc.CapabilitiesStub(channel)
    content = service_pb2_grpc.ContentStorageStub(channel)
    jobs = service_pb2_grpc.BakeJobsStub(channel)

    # No token, wrong token: UNAUTHENTICATED.
    for metadata in ([], [("authorization", "Bearer nope")]):
        try:
            caps_stub.GetCapabilities(service_pb2.GetCapabilitiesRequest(), metadata=metadata)
            fail("a call without a valid token succeeded")
        except grpc.RpcError as e:
            check(e.code() == grpc.StatusCode.UNAUTHENTICATED, "expected UNAUTHENTICATED, got %s" % e.code())
    caps = caps_stub.GetCapabilities(service_pb2.GetCapabilitiesRequest(), metadata=auth)
    check(caps.digest_function == "SHA256", "digest function %r" % caps.digest_function)

    # Upload the mesh in 64-byte chunks (several messages), after FindMissingBlobs says so.
    digest = job_pb2.Digest(hash=hashlib.sha256(FLOOR_OBJ).hexdigest(), size_bytes=len(FLOOR_OBJ))
    missing = content.FindMissingBlobs(
        service_pb2.FindMissingBlobsRequest(blob_digests=[digest]), metadata=auth)
    check(len(missing.missing_blob_digests) == 1, "the new blob is not reported missing")

    def chunks():
        for offset in range(0, len(FLOOR_OBJ), 64):
            yield service_pb2.WriteBlobRequest(
                digest=digest if offset == 0 else None, write_offset=offset,
                data=FLOOR_OBJ[offset:offset + 64], finish_write=offset + 64 >= len(FLOOR_OBJ))

    written = content.WriteBlob(chunks(), metadata=auth)
    check(written.committed_size == len(FLOOR_OBJ), "committed %d" % written.committed_size)
    missing = content.FindMissingBlobs(
        service_pb2.FindMissingBlobsRequest(blob_digests=[digest]), metadata=auth)
    check(len(missing.missing_blob_digests) == 0, "the uploaded blob is still missing")

    # A bad job (NaN albedo) is INVALID_ARGUMENT naming the field.
    spec = json_format.Parse(JOB_JSON % (digest.hash, digest.size_bytes), job_pb2.JobSpec())
    bad = job_pb2.JobSpec()
    bad.CopyFrom(spec)
    bad.scene.materials[0].albedo[1] = float("nan")
    try:
        jobs.CreateBakeJob(service_pb2.CreateBakeJobRequest(job=bad), metadata=auth)
        fail("a NaN albedo was accepted")
    except grpc.RpcError as e:
        check(e.code() == grpc.StatusCode.INVALID_ARGUMENT and
              "scene.materials[0].albedo[1]" in e.details(), "NaN: %s %s" % (e.code(), e.details()))

    # Submit, watch to the end.
    job = jobs.CreateBakeJob(service_pb2.CreateBakeJobRequest(request_id="interop-1", job=spec),
                             metadata=auth)
    check(job.name.startswith("bakeJobs/"), "job name %r" % job.name)
    states = []
    for update in jobs.WatchBakeJob(service_pb2.WatchBakeJobRequest(name=job.name), metadata=auth,
                                    timeout=120):
        states.append(update.state)
        final = update
    check(final.state == service_pb2.BakeJob.SUCCEEDED, "final state %s: %s" % (
        service_pb2.BakeJob.State.Name(final.state), final.error.message))
    check(states == sorted(states), "states went backwards: %s" % states)
    check(final.progress.probes_done == 9, "probes done %d" % final.progress.probes_done)

    # Read the volume back in two ranges, check the digest.
    volume = final.result.volume
    half = volume.size_bytes // 2
    data = b""
    for offset, limit in ((0, half), (half, 0)):
        for chunk in content.ReadBlob(service_pb2.ReadBlobRequest(
                digest=volume, read_offset=offset, read_limit=limit), metadata=auth):
            data += chunk.data
    check(len(data) == volume.size_bytes, "read %d of %d bytes" % (len(data), volume.size_bytes))
    check(hashlib.sha256(data).hexdigest() == volume.hash, "volume digest mismatch")
    try:
        list(content.ReadBlob(service_pb2.ReadBlobRequest(
            digest=volume, read_offset=volume.size_bytes + 1), metadata=auth))
        fail("reading past the end succeeded")
    except grpc.RpcError as e:
        check(e.code() == grpc.StatusCode.OUT_OF_RANGE, "past the end: %s" % e.code())

    if args.expect_vdb:
        import pyopenvdb
        path = os.path.join(os.path.dirname(port_file), "result.vdb")
        with open(path, "wb") as f:
            f.write(data)
        grids, metadata = pyopenvdb.readAll(path)
        names = sorted(g.name for g in grids)
        check("radiance_sh_00" in names and "radiance_sh_03" in names and "validity" in names,
              "grids %s" % names)
        check(metadata.get("sh_order") == 1, "sh_order %r" % metadata.get("sh_order"))
        validity = next(g for g in grids if g.name == "validity")
        check(validity.activeVoxelCount() == 9, "active probes %d" % validity.activeVoxelCount())
    channel.close()


if __name__ == "__main__":
    main()
