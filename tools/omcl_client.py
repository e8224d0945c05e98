#!/usr/bin/env python3
"""A small Python client of `omcl serve` (gRPC), and an example.

The gRPC stubs are generated from the project's proto/omcl.proto with
grpcio-tools the first time they are needed (into .deps/pyproto/, never
committed, or $XDG_CACHE_HOME/omcl/pyproto/ when that cannot be written). grpcio and grpcio-tools come from PyPI: `make deps`
(tools/setup.sh) installs them into .deps/python/.

As a library:

    client = OmclClient("127.0.0.1:50051", token)
    sid = client.create_session("room", camera, initial_pose=(t, q))
    # or, with the server's warnings about the start (a pose outside the map):
    r = client.open_session("room", camera, initial_pose=(t, q)); r.warnings
    for update in client.stream(frames):  # dicts, see frame()
        print(update.pose.pose.pose.position)

As an example, it streams a synthetic sequence (`omcl sim indoor
--features`: intrinsics.txt, poses.txt, odometry.txt, features/NNNNNN.npy)
and prints one line per pose:

    OMCL_TOKEN=... python3 tools/omcl_client.py --map room --sequence seq

With --images it sends the sequence's camera images instead (the files
rgb/NNNNNN.png or .jpg as they are), which the server decodes and encodes
with the map's image encoder (`omcl serve --image-model NAME=MODEL`): the
client needs no model and no imaging library.

With --baseline sedar|simp the session tracks the camera with one of
Table I's baselines on a map served on its floor plan (`omcl serve
--floorplan NAME`, with its class table); SIMP* frames carry the depth of
depth/NNNNNN.png (16-bit PNG, --depth-scale units a metre).

The token is read from --token-file or the OMCL_TOKEN environment variable,
never from the command line.
"""

import argparse
import array
import ast
import math
import os
import queue
import signal
import sys
import threading

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PROTO_DIR = os.path.join(ROOT, "proto")
DEPS = os.path.join(ROOT, ".deps", "python")
STUBS = os.path.join(ROOT, ".deps", "pyproto")


def stubs_fresh(d, proto):
    out = os.path.join(d, "omcl_pb2_grpc.py")
    return os.path.exists(out) and os.path.getmtime(out) >= os.path.getmtime(proto)


def user_stubs_dir(proto):
    """A per-user cache for the stubs ($XDG_CACHE_HOME/omcl/pyproto, else
    ~/.cache/...), one folder per .proto content so that checkouts of
    different versions do not share stubs."""
    import hashlib

    with open(proto, "rb") as f:
        digest = hashlib.sha256(f.read()).hexdigest()[:16]
    cache = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return os.path.join(cache, "omcl", "pyproto", digest)


def writable_dir(d):
    try:
        os.makedirs(d, exist_ok=True)
    except OSError:
        return False
    return os.access(d, os.W_OK)


def load_stubs():
    """Imports omcl_pb2 and omcl_pb2_grpc, generating them when missing or
    older than the .proto: into .deps/pyproto/, or into a per-user cache
    when that cannot be written (a read-only checkout or install)."""
    if os.path.isdir(DEPS) and DEPS not in sys.path:
        sys.path.insert(0, DEPS)
    proto = os.path.join(PROTO_DIR, "omcl.proto")
    stubs = STUBS
    if not stubs_fresh(stubs, proto) and not writable_dir(stubs):
        stubs = user_stubs_dir(proto)
    if not stubs_fresh(stubs, proto):
        try:
            from grpc_tools import protoc
        except ImportError:
            sys.exit("omcl_client: grpcio-tools is missing: run `make deps` (tools/setup.sh)")
        import importlib.resources

        if not writable_dir(stubs):
            sys.exit(f"omcl_client: cannot write the generated stubs into {STUBS} nor {stubs}")
        well_known = str(importlib.resources.files("grpc_tools") / "_proto")
        rc = protoc.main(
            [
                "protoc",
                f"-I{PROTO_DIR}",
                f"-I{well_known}",
                f"--python_out={stubs}",
                f"--grpc_python_out={stubs}",
                proto,
            ]
        )
        if rc != 0:
            sys.exit(f"omcl_client: protoc failed on {proto} ({rc})")
    if stubs not in sys.path:
        sys.path.insert(0, stubs)
    import omcl_pb2
    import omcl_pb2_grpc

    return omcl_pb2, omcl_pb2_grpc


pb, pb_grpc = load_stubs()
import grpc  # noqa: E402  (after load_stubs put .deps/python on the path)


def pose_msg(t, q):
    """A Pose from a translation (x, y, z) and a quaternion (x, y, z, w)."""
    return pb.Pose(
        position=pb.Point(x=t[0], y=t[1], z=t[2]),
        orientation=pb.Quaternion(x=q[0], y=q[1], z=q[2], w=q[3]),
    )


def header(stamp, frame_id="camera"):
    sec = int(stamp // 1)
    nanosec = min(int(round((stamp - sec) * 1e9)), 999_999_999)
    return pb.Header(stamp=pb.Time(sec=sec, nanosec=nanosec), frame_id=frame_id)


class OmclClient:
    """gRPC calls of `omcl serve`, with the bearer token on every call."""

    def __init__(self, target, token, root_cert=None):
        if root_cert is None:
            channel = grpc.insecure_channel(target)
        else:
            channel = grpc.secure_channel(target, grpc.ssl_channel_credentials(root_cert))
        self.stub = pb_grpc.LocalizationStub(channel)
        self.metadata = (("authorization", f"Bearer {token}"),)

    def list_maps(self):
        return self.stub.ListMaps(pb.ListMapsRequest(), metadata=self.metadata).maps

    def list_sessions(self):
        return self.stub.ListSessions(pb.ListSessionsRequest(), metadata=self.metadata).sessions

    def create_session(self, map_name, camera, **kw):
        """The new session's id; see open_session."""
        return self.open_session(map_name, camera, **kw).session_id

    def open_session(self, map_name, camera, initial_pose=None, prompt=None,
                     particles=None, rays=None, seed=0, recovery=False,
                     early_reject=False, ground=False, filter_name="", baseline="",
                     max_depth=None):
        """A CreateSessionResponse: session_id, and warnings about the
        start (a pose from which the camera cannot see the map).
        camera: (fx, fy, cx, cy, width, height); initial_pose: (t, q);
        prompt: words; neither: global localization. early_reject: two-pass
        likelihoods (omcl localize --early-reject); ground: the camera held
        at its start's height and tilt (omcl localize --ground); filter_name:
        a tuned filter by name (omcl localize --filter; empty: the map's
        default); baseline: "sedar" or "simp" for one of Table I's
        baselines on a floor plan (empty: OMCL); max_depth: a SIMP*
        session places only pixels at most this deep (metres)."""
        fx, fy, cx, cy, w, h = camera
        req = pb.CreateSessionRequest(
            map=map_name,
            camera=pb.CameraInfo(fx=fx, fy=fy, cx=cx, cy=cy, width=w, height=h),
            seed=seed,
            recovery=recovery,
            early_reject=early_reject,
            ground=ground,
            filter=filter_name,
            baseline=baseline,
        )
        if particles is not None:
            req.particles = particles
        if rays is not None:
            req.rays = rays
        if max_depth is not None:
            req.max_depth = max_depth
        if initial_pose is not None:
            req.initial_pose.pose.pose.CopyFrom(pose_msg(*initial_pose))
        elif prompt:
            req.prompt.words.extend(prompt)
        else:
            getattr(req, "global").SetInParent()  # `global` is a Python keyword
        return self.stub.CreateSession(req, metadata=self.metadata)

    def close_session(self, session_id):
        return self.stub.CloseSession(
            pb.CloseSessionRequest(session_id=session_id), metadata=self.metadata
        )

    def localize(self, frame, timeout=None):
        return self.stub.Localize(frame, metadata=self.metadata, timeout=timeout)

    def stream(self, frames):
        """Frames in, StreamResponse out (pose or an in-band error)."""
        return self.stub.Stream(iter(frames), metadata=self.metadata)


def frame(session_id, stamp, odom_t, odom_q, grid=None, labels=None, rgb=None,
          compressed=None, want_particles=False, depth=None):
    """A Frame: grid = (height, width, dim, floats), labels = (width,
    height, ints), rgb = (width, height, bytes: row-major RGB, 3 a pixel)
    or compressed = (format, bytes of a PNG or JPEG file); images are
    encoded on the server. depth = (width, height, metres: row-major, 0
    none), for a SIMP* session."""
    f = pb.Frame(session_id=session_id, header=header(stamp),
                 odometry=pose_msg(odom_t, odom_q), want_particles=want_particles)
    if depth is not None:
        set_depth(f, depth)
    if grid is not None:
        h, w, d, data = grid
        f.grid.height, f.grid.width, f.grid.dim = h, w, d
        f.grid.data.extend(data)
    elif labels is not None:
        w, h, ids = labels
        f.labels.width, f.labels.height = w, h
        f.labels.labels.extend(ids)
    elif rgb is not None:
        w, h, data = rgb
        f.image.width, f.image.height, f.image.rgb = w, h, bytes(data)
    elif compressed is not None:
        f.compressed.format, f.compressed.data = compressed
    return f


def set_depth(f, depth):
    """Gives Frame f depth = (width, height, metres)."""
    w, h, metres = depth
    f.depth.width, f.depth.height = w, h
    f.depth.depth.extend(metres)


# --- reading a synthetic sequence, without numpy ---------------------------

def read_tum(path):
    """[(stamp, (tx, ty, tz), (qx, qy, qz, qw))] of a TUM file."""
    out = []
    with open(path) as f:
        for line in f:
            v = line.replace(",", " ").split()
            if not v or v[0].startswith("#"):
                continue
            x = [float(s) for s in v]
            out.append((x[0], tuple(x[1:4]), tuple(x[4:8])))
    return out


def read_npy_f32(path):
    """(shape, floats) of a little-endian float32 .npy file."""
    with open(path, "rb") as f:
        if f.read(6) != b"\x93NUMPY":
            raise ValueError(f"{path}: not a .npy file")
        major = f.read(2)[0]
        n = int.from_bytes(f.read(2 if major == 1 else 4), "little")
        head = ast.literal_eval(f.read(n).decode("latin1"))
        if head["descr"] != "<f4" or head["fortran_order"]:
            raise ValueError(f"{path}: expected little-endian float32 in C order, got {head}")
        data = array.array("f")
        data.frombytes(f.read())
    if sys.byteorder != "little":
        data.byteswap()
    return tuple(head["shape"]), data


def _paeth(a, b, c):
    p = a + b - c
    pa, pb_, pc = abs(p - a), abs(p - b), abs(p - c)
    if pa <= pb_ and pa <= pc:
        return a
    return b if pb_ <= pc else c


def read_png_gray16(path, size=None):
    """(width, height, values) of a 16-bit greyscale PNG (a depth image),
    without an imaging library: zlib and PNG's five row filters. size:
    the (width, height) it must have, checked before any pixel is read."""
    import struct
    import zlib
    with open(path, "rb") as f:
        data = f.read()
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError(f"{path}: not a PNG file")
    pos, idat, head = 8, [], None
    while pos + 8 <= len(data):
        n, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + n]
        if kind == b"IHDR":
            if len(body) != 13:
                raise ValueError(f"{path}: an IHDR chunk of {len(body)} bytes, not 13")
            head = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
        pos += 12 + n
    if head is None:
        raise ValueError(f"{path}: no IHDR chunk")
    w, h, bits, colour, _, _, interlace = head
    if w == 0 or h == 0:
        raise ValueError(f"{path}: a {w} x {h} image")
    if size is not None and (w, h) != tuple(size):
        raise ValueError(f"{path}: a {w} x {h} depth image, the camera is {size[0]} x {size[1]}")
    if (bits, colour, interlace) != (16, 0, 0):
        raise ValueError(f"{path}: a depth image must be a 16-bit greyscale PNG, not "
                         f"interlaced (bit depth {bits}, colour type {colour}, "
                         f"interlace {interlace})")
    stride, bpp = 2 * w, 2
    # Never more than the image holds: a small file cannot inflate to
    # gigabytes.
    want = h * (stride + 1)
    try:
        raw = zlib.decompressobj().decompress(b"".join(idat), want + 1)
    except zlib.error as e:
        raise ValueError(f"{path}: corrupt image data: {e}") from None
    if len(raw) != want:
        raise ValueError(f"{path}: {len(raw)} bytes of pixels, expected {want}")
    out, prev = array.array("H"), bytearray(stride)
    for y in range(h):
        kind = raw[y * (stride + 1)]
        row = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        if kind == 1:
            for x in range(bpp, stride):
                row[x] = (row[x] + row[x - bpp]) & 255
        elif kind == 2:
            for x in range(stride):
                row[x] = (row[x] + prev[x]) & 255
        elif kind == 3:
            for x in range(stride):
                left = row[x - bpp] if x >= bpp else 0
                row[x] = (row[x] + ((left + prev[x]) >> 1)) & 255
        elif kind == 4:
            for x in range(stride):
                left = row[x - bpp] if x >= bpp else 0
                up_left = prev[x - bpp] if x >= bpp else 0
                row[x] = (row[x] + _paeth(left, prev[x], up_left)) & 255
        elif kind != 0:
            raise ValueError(f"{path}: row {y} has unknown filter {kind}")
        vals = array.array("H")
        vals.frombytes(bytes(row))
        if sys.byteorder == "little":
            vals.byteswap()  # PNG samples are big-endian
        out.extend(vals)
        prev = row
    return w, h, out


def read_depth(seq, i, units_per_metre, size):
    """(width, height, metres) of frame i's depth/NNNNNN.png, which must
    be of the camera's size = (width, height)."""
    path = os.path.join(seq, "depth", f"{i:06}.png")
    w, h, v = read_png_gray16(path, size)
    # As omcl reads it, in float32: the sample times float32(1 / units).
    # The product of two float32 values is exact in a double, so one
    # rounding to float32 (the array) gives omcl's value to the bit.
    scale = array.array("f", [1.0 / units_per_metre])[0]
    return w, h, array.array("f", [x * scale for x in v])


def image_file(seq, i):
    """(path, format) of frame i's camera image: rgb/NNNNNN.png, else .jpg."""
    for ext, fmt in ((".png", "png"), (".jpg", "jpeg"), (".jpeg", "jpeg")):
        path = os.path.join(seq, "rgb", f"{i:06}{ext}")
        if os.path.exists(path):
            return path, fmt
    raise OSError(f"{os.path.join(seq, 'rgb', f'{i:06}.png')}: no such file (nor .jpg)")


def read_camera(seq):
    with open(os.path.join(seq, "intrinsics.txt")) as f:
        v = f.read().split()
    fx, fy, cx, cy = (float(s) for s in v[:4])
    return fx, fy, cx, cy, int(v[4]), int(v[5])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--target", default="127.0.0.1:50051", help="gRPC address of omcl serve")
    ap.add_argument("--token-file", help="file with the bearer token (default: $OMCL_TOKEN)")
    ap.add_argument("--tls-ca", help="PEM root certificate, for a server with --tls-cert")
    ap.add_argument("--map", required=True, help="map name on the server")
    ap.add_argument("--sequence", required=True,
                    help="folder with intrinsics.txt, poses.txt, odometry.txt, and features/ "
                         "(or rgb/ with --images)")
    ap.add_argument("--images", action="store_true",
                    help="send the camera images rgb/NNNNNN.png (or .jpg) as they are, "
                         "decoded and encoded on the server with the map's image encoder "
                         "(omcl serve --image-model), instead of features/NNNNNN.npy")
    ap.add_argument("--frames", type=int, help="stream at most this many frames (at least 1)")
    ap.add_argument("--particles", type=int)
    ap.add_argument("--rays", type=int)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--early-reject", action="store_true",
                    help="two-pass likelihoods (omcl localize --early-reject)")
    ap.add_argument("--ground", action="store_true",
                    help="hold the camera at its start's height, roll and pitch, as a "
                         "robot on a flat floor carries it (omcl localize --ground)")
    ap.add_argument("--filter", default="",
                    help="a tuned filter by name: indoor, floor-plan, six-dof, "
                         "six-dof-point-cloud, street (omcl localize --filter; "
                         "default: the map's)")
    ap.add_argument("--global", dest="global_", action="store_true",
                    help="start globally instead of at the first ground-truth pose")
    ap.add_argument("--baseline", choices=["sedar", "simp"], default="",
                    help="track with one of Table I's baselines on a map served on its "
                         "floor plan (omcl serve --floorplan NAME; omcl localize "
                         "--baseline): SeDAR* or SIMP*, which also sends depth/NNNNNN.png")
    ap.add_argument("--depth-scale", type=float, default=5000.0,
                    help="--baseline simp: depth PNG units per metre (default 5000, TUM's)")
    ap.add_argument("--max-depth", type=float, default=None, metavar="METRES",
                    help="--baseline simp: place only pixels at most this deep (omcl "
                         "localize --max-depth; default: every pixel with a depth)")
    a = ap.parse_args()
    if not (a.depth_scale > 0 and math.isfinite(a.depth_scale)):
        ap.error(f"--depth-scale {a.depth_scale}: give a positive number of units a metre")
    if a.frames is not None and a.frames < 1:
        ap.error(f"--frames {a.frames}: give at least 1 (leave it out for every frame)")
    # SIGTERM ends the run as Ctrl-C does: the session is closed first.
    signal.signal(signal.SIGINT, interrupted)
    signal.signal(signal.SIGTERM, interrupted)
    # One line for what went wrong, not a traceback: the server's status,
    # or the file that could not be read.
    try:
        run(a)
    except grpc.RpcError as e:
        sys.exit(f"omcl_client: {e.code().name}: {e.details()} (server {a.target})")
    except (OSError, ValueError) as e:
        sys.exit(f"omcl_client: {e}")
    except KeyboardInterrupt:
        sys.exit(130)
    except Terminated:
        sys.exit(143)


class Terminated(BaseException):
    """SIGTERM, raised in the main thread (as KeyboardInterrupt is for
    Ctrl-C) so that the session is closed on the way out."""


# The frame stream in progress, and the signal that stopped it.
_stream = {"call": None, "signal": None}


def _stop(signum):
    raise KeyboardInterrupt() if signum == signal.SIGINT else Terminated()


def interrupted(signum, frame):
    """SIGINT or SIGTERM. While frames stream, the stream is cancelled from
    another thread and the main loop, woken by the cancellation, stops
    (closing the session) on its own: an exception raised here, inside
    grpc's iteration, could leave grpc's lock held and the close waiting
    for it for ever (seen once in CI, 2026-12-02). Otherwise, or on a
    second signal, at once."""
    call = _stream["call"]
    if call is None or _stream["signal"] is not None:
        _stop(signum)
    _stream["signal"] = signum
    threading.Thread(target=call.cancel, daemon=True).start()


def run(a):
    if a.token_file:
        with open(a.token_file) as f:
            token = f.readline().strip()
    else:
        token = os.environ.get("OMCL_TOKEN")
        if not token:
            sys.exit("omcl_client: no token: pass --token-file FILE or set OMCL_TOKEN")
    root = open(a.tls_ca, "rb").read() if a.tls_ca else None
    client = OmclClient(a.target, token, root)

    names = [m.name for m in client.list_maps()]
    if a.map not in names:
        sys.exit(f"omcl_client: no map {a.map!r} on the server (it has {names})")
    gt = read_tum(os.path.join(a.sequence, "poses.txt"))
    odom = read_tum(os.path.join(a.sequence, "odometry.txt"))
    n = min(len(gt), len(odom), a.frames if a.frames is not None else len(gt))
    camera = read_camera(a.sequence)
    init = None if a.global_ else (gt[0][1], gt[0][2])
    created = client.open_session(a.map, camera, initial_pose=init,
                                  particles=a.particles, rays=a.rays, seed=a.seed,
                                  early_reject=a.early_reject, ground=a.ground,
                                  filter_name=a.filter, baseline=a.baseline,
                                  max_depth=a.max_depth)
    sid = created.session_id
    for w in created.warnings:
        print(f"omcl_client: warning from the server: {w}", file=sys.stderr)

    # One frame at a time through the stream: the next frame is sent once
    # the previous one is answered, so none is dropped (a camera sending at
    # its own rate would rather let the server keep the latest).
    answered = queue.Queue()
    # A file that cannot be read ends the stream; grpc runs this generator
    # on its own thread, so the reason is handed back here. `sent` says
    # which frame (index, file) each answer is for: one is in flight.
    unreadable = []
    sent = queue.Queue()

    def frames():
        for i in range(n):
            try:
                if a.images:
                    path, fmt = image_file(a.sequence, i)
                    with open(path, "rb") as fh:
                        data = fh.read()
                    f = frame(sid, gt[i][0], odom[i][1], odom[i][2], compressed=(fmt, data))
                else:
                    path = os.path.join(a.sequence, "features", f"{i:06}.npy")
                    shape, data = read_npy_f32(path)
                    h, w, d = shape
                    f = frame(sid, gt[i][0], odom[i][1], odom[i][2], grid=(h, w, d, data))
                if a.baseline == "simp":
                    set_depth(f, read_depth(a.sequence, i, a.depth_scale, camera[4:6]))
            except (OSError, ValueError) as e:
                unreadable.append(str(e))
                return
            sent.put((i, path))
            yield f
            answered.get()

    count, refused, precondition = 0, 0, None
    call = client.stream(frames())
    _stream["call"] = call
    try:
        for r in call:
            i, path = sent.get()
            answered.put(True)
            if r.HasField("error"):
                # FAILED_PRECONDITION is about the session or its map (a
                # map without an image encoder, say), not this frame:
                # every frame after it would be refused alike.
                if r.error.code == "FAILED_PRECONDITION":
                    precondition = f"{r.error.message} (at frame {i:06}, {path})"
                    break
                print(f"error {r.error.code}: {r.error.message} (frame {i:06}, {path})",
                      file=sys.stderr)
                refused += 1
                continue
            p = r.pose.pose.pose.pose
            t, q = p.position, p.orientation
            print(f"frame {i:06} stamp {gt[i][0]!r} pose "
                  f"{t.x!r} {t.y!r} {t.z!r} {q.x!r} {q.y!r} {q.z!r} {q.w!r} "
                  f"confidence {r.pose.confidence:.3f} step_ms {r.pose.step_ms:.1f}", flush=True)
            count += 1
    except grpc.RpcError as e:
        if _stream["signal"] is not None:
            _stop(_stream["signal"])
        if e.code() == grpc.StatusCode.UNAVAILABLE:
            sys.exit(f"omcl_client: UNAVAILABLE: {e.details()} (server {a.target}), after "
                     f"{count} poses from session {sid}")
        raise
    finally:
        # Also on Ctrl-C and SIGTERM. The session is the server's to expire
        # if it has gone meanwhile (the stream's own error is the one to
        # report).
        _stream["call"] = None
        call.cancel()
        try:
            client.close_session(sid)
        except grpc.RpcError:
            pass
    if _stream["signal"] is not None:
        # The signal came as the stream ended.
        _stop(_stream["signal"])
    if precondition:
        sys.exit(f"omcl_client: FAILED_PRECONDITION: {precondition}; stopped (after "
                 f"{count} poses)")
    if unreadable:
        sys.exit(f"omcl_client: {unreadable[0]} (after {count} poses)")
    print(f"{count} poses from session {sid}", file=sys.stderr)
    if refused:
        sys.exit(f"omcl_client: the server refused {refused} of {count + refused} frames "
                 f"(named above)")


if __name__ == "__main__":
    main()
