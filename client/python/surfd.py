"""surfd.py - the Python client of surfd (standard library only, one file).

Every route of the HTTP contract (api/openapi.yaml) as a method of :class:`Client`. Work that the
server runs as a job (renders, models, volumes, isosurfaces, edits, matrices, meshes) is submitted
with ``Prefer: respond-async`` and followed to its end, polling from 0.1 s backing off to 2 s;
the method returns the job's result: parsed JSON (``dict``) for JSON answers, ``bytes`` for files
(images, meshes). Every refusal or failure raises :class:`SurfdError`, which carries the HTTP
status and the problem object (RFC 9457: ``title``, ``detail``, ``errors[].pointer``).

    >>> import surfd
    >>> c = surfd.Client("http://127.0.0.1:8080", token=None)   # or SURFD_URL, SURFD_TOKEN
    >>> m = c.model("../shared/data/contours/synthetic_ellipsoid.json", caps="dome")
    >>> m["volume_mm3"]
    >>> open("e.stl", "wb").write(c.mesh(m["id"], format="stl"))
    >>> png = c.view(m["id"], width=400, height=300, azimuth=45)
"""
from __future__ import annotations

import json
import os
import ssl
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path
from typing import Any, Callable, Dict, List, Mapping, Optional, Union

__all__ = ["Client", "SurfdError"]

Body = Union[bytes, str, os.PathLike]
Options = Mapping[str, Any]



# A file's type by its extension where the daemon has no GET /formats (before issue 47) to say it.
_OLD_TYPES = {".json": "application/json", ".dcm": "application/dicom", ".bpt": "model/x-bpt", ".nurbs": "model/vrml",
              ".wrl": "model/vrml", ".igs": "model/iges", ".iges": "model/iges", ".nrrd": "application/x-nrrd",
              ".mha": "application/x-metaimage", ".nii": "application/x-nifti"}


class SurfdError(Exception):
    """A request surfd refused or a job that did not succeed.

    status: the HTTP status (0 when surfd could not be reached); problem: the problem object
    (``{"title", "status", "detail", "errors": [{"pointer", "message"}]}``), or ``{}``;
    job: the job's id when the error belongs to a job."""

    def __init__(self, status: int, problem: Optional[Dict[str, Any]] = None, job: Optional[str] = None):
        self.status = status
        self.problem: Dict[str, Any] = problem or {}
        self.job = job
        super().__init__(self._text())

    @property
    def pointer(self) -> Optional[str]:
        """The first offending field's JSON pointer ("/objects/0/knots_u/2", "?iso"), if any."""
        errs = self.problem.get("errors") or []
        return errs[0].get("pointer") if errs else None

    def _text(self) -> str:
        p = self.problem
        text = "%d %s" % (self.status, p.get("detail") or p.get("title") or "")
        if self.pointer:
            text += " at " + self.pointer
        if self.job:
            text += " (job %s)" % self.job
        return text


class Client:
    """A surfd server. url defaults to $SURFD_URL, else http://127.0.0.1:8080; token (sent as a
    bearer token) to $SURFD_TOKEN. timeout: seconds a single HTTP request may take. progress: a
    function called with each polled job resource while a job runs (None: quiet). cafile: the
    certificate authority (PEM) a TLS daemon signed by a site's own CA is checked against, else
    $SURFD_CACERT, else the system's."""

    def __init__(self, url: Optional[str] = None, token: Optional[str] = None, timeout: float = 600.0,
                 progress: Optional[Callable[[Dict[str, Any]], None]] = None, cafile: Optional[str] = None):
        self.url = (url or os.environ.get("SURFD_URL") or "http://127.0.0.1:8080").rstrip("/")
        self.token = token if token is not None else os.environ.get("SURFD_TOKEN") or None
        self.timeout = timeout
        self.progress = progress
        self._formats: Optional[List[Dict[str, Any]]] = None  # GET /formats, once needed
        cafile = cafile or os.environ.get("SURFD_CACERT") or None
        self._tls = ssl.create_default_context(cafile=cafile) if cafile else None

    # ---- the HTTP layer -------------------------------------------------------------------

    def request(self, method: str, path: str, body: Optional[bytes] = None, content_type: Optional[str] = None,
                headers: Optional[Mapping[str, str]] = None) -> "Response":
        """One request; a status of 400 or above raises SurfdError with the problem."""
        h = {"Accept": "*/*"}
        if self.token:
            h["Authorization"] = "Bearer " + self.token
        if content_type:
            h["Content-Type"] = content_type
        h.update(headers or {})
        req = urllib.request.Request(self.url + path, data=body, method=method, headers=h)
        try:
            with urllib.request.urlopen(req, timeout=self.timeout, context=self._tls) as r:
                return Response(r.status, dict(r.headers.items()), r.read())
        except urllib.error.HTTPError as e:
            data = e.read()
            try:
                problem = json.loads(data) if data else {}
            except ValueError:
                problem = {"detail": data.decode("utf-8", "replace")}
            raise SurfdError(e.code, problem, e.headers.get("X-Job-Id")) from None
        except urllib.error.URLError as e:
            raise SurfdError(0, {"detail": "surfd unreachable at %s: %s" % (self.url, e.reason)}) from None

    def _media_of(self, path: Path, route: str) -> Optional[str]:
        """A file's media type on route by its extension, from the daemon's table of formats (GET
        /formats, fetched once); None when it has none (the daemon then sniffs the body)."""
        if self._formats is None:
            try:
                self._formats = self.request("GET", "/formats").parsed()["formats"]
            except SurfdError:  # (not kept: asked again next time) a daemon before GET /formats: the usual types
                return _OLD_TYPES.get(path.suffix.lower())
        name = path.name.lower()
        for f in self._formats:
            if route in f["routes"] and any(name.endswith(e) for e in f["extensions"]):
                return f["media"][0]
        return None

    def _job(self, method: str, path: str, options: Optional[Options] = None, body: Optional[Body] = None,
             content_type: Optional[str] = None) -> Union[Dict[str, Any], bytes]:
        """Submits a job (respond-async), follows it, returns its result."""
        data, ctype = _body(body, content_type, lambda p: self._media_of(p, path))
        r = self.request(method, path + _query(options), data, ctype, {"Prefer": "respond-async"})
        if r.status == 202:
            job = json.loads(r.body)
            self.wait(job["id"])
            r = self.request("GET", "/jobs/%s/result" % job["id"])
        return r.parsed()

    # ---- jobs -----------------------------------------------------------------------------

    def jobs(self, state: Optional[str] = None) -> List[Dict[str, Any]]:
        """GET /jobs (newest first); state: queued, running, succeeded, failed or cancelled."""
        return self.request("GET", "/jobs" + _query({"state": state})).parsed()["jobs"]

    def job(self, job_id: str) -> Dict[str, Any]:
        """GET /jobs/{id}: the job resource (state, progress, error...)."""
        return self.request("GET", "/jobs/" + job_id).parsed()

    def wait(self, job_id: str, timeout: Optional[float] = None) -> Dict[str, Any]:
        """Polls the job until it ends (0.1 s, backing off to 2 s); returns the job resource when it
        succeeded, else raises SurfdError with its problem (a cancelled job: status 409)."""
        start, pause = time.monotonic(), 0.1
        while True:
            job = self.job(job_id)
            if self.progress:
                self.progress(job)
            if job["state"] == "succeeded":
                return job
            if job["state"] in ("failed", "cancelled"):
                problem = job.get("error") or {"title": "Conflict", "detail": "the job was " + job["state"]}
                raise SurfdError(problem.get("status", 409), problem, job_id)
            if timeout is not None and time.monotonic() - start > timeout:
                raise SurfdError(0, {"detail": "the job is still %s after %g s" % (job["state"], timeout)}, job_id)
            time.sleep(pause)
            pause = min(2.0, pause * 1.5)

    def result(self, job_id: str) -> Union[Dict[str, Any], bytes]:
        """GET /jobs/{id}/result: the ended job's result as its route answers it."""
        return self.request("GET", "/jobs/%s/result" % job_id).parsed()

    def cancel(self, job_id: str) -> Dict[str, Any]:
        """POST /jobs/{id}/cancel."""
        return self.request("POST", "/jobs/%s/cancel" % job_id, b"").parsed()

    def submit(self, route: str, body: Optional[Body] = None, content_type: Optional[str] = None,
               **options: Any) -> str:
        """POSTs a job without waiting for it (Prefer: respond-async): its id."""
        data, ctype = _body(body, content_type, lambda p: self._media_of(p, route))
        r = self.request("POST", route + _query(options), data if data is not None else b"", ctype,
                         {"Prefer": "respond-async"})
        return r.headers.get("X-Job-Id") or json.loads(r.body)["id"]

    # ---- the routes -----------------------------------------------------------------------

    def render(self, scene: Body, content_type: Optional[str] = None, **options: Any) -> bytes:
        """POST /render: a scene (JSON, .bpt, VRML, IGES) to an image (PNG unless output=exr|tiff).
        options: width, height, output, method, azimuth, elevation, eye, target, up, fov,
        projection, view, view_height, shadows (vectors as "x,y,z" or a sequence)."""
        return self._job("POST", "/render", options, scene, content_type)

    def model(self, contours: Body, content_type: Optional[str] = None, **options: Any) -> Dict[str, Any]:
        """POST /model: contours (JSON), an RT Structure Set (.dcm) or a matrix model; the model
        resource, or {"models": [...]} for several ROIs. options: method, caps, roi, parameterisation."""
        return self._job("POST", "/model", options, contours, content_type)

    def volume(self, contours: Body, content_type: Optional[str] = None, **options: Any) -> Dict[str, Any]:
        """POST /volume: the volume figures of contours or a closed scene, nothing stored."""
        return self._job("POST", "/volume", options, contours, content_type)

    def isosurface(self, volume: Body, content_type: Optional[str] = None, **options: Any) -> Dict[str, Any]:
        """POST /isosurface: a volume (NRRD, MetaImage, NIfTI, raw samples with dims and type, a
        directory of a DICOM series' images, a detached header with its data file, one multi-frame DICOM
        image: an Enhanced CT or MR, an RT Dose with iso in Gy, a Segmentation with segment=N and iso 0.5)
        or an FRep object; the model resource. options: iso, dims, type, spacing, origin, levels,
        max_error, features, closed, name, segment; for a label map (no iso) label=N (that label's
        model) or labels="all" (one model a label: {"models": [...]})."""
        return self._job("POST", "/isosurface", options, volume, content_type)

    def edit(self, model_id: str, samples: Optional[Body] = None, region: Any = None,
             frep: Optional[Dict[str, Any]] = None) -> Dict[str, Any]:
        """POST /models/{id}/edit: raw samples of region (x0,y0,z0,nx,ny,nz), or for an FRep model
        frep = {"op": ..., "object": {...}}; the updated model resource."""
        if frep is not None:
            return self._job("POST", "/models/%s/edit" % model_id, None, json.dumps(frep).encode(), "application/json")
        return self._job("POST", "/models/%s/edit" % model_id, {"region": region}, samples, "application/octet-stream")

    def matrix(self, volume: Optional[Body] = None, model: Optional[str] = None, size: Any = None,
               content_type: Optional[str] = None, **options: Any) -> Dict[str, Any]:
        """POST /matrix-model: the six relief matrices of a volume (options as isosurface's), or of a
        stored model (model=ID, size=(N, M, K))."""
        if model is not None:
            return self._job("POST", "/matrix-model", dict(options, model=model, size=size), b"")
        return self._job("POST", "/matrix-model", options, volume, content_type)

    def models(self) -> List[Dict[str, Any]]:
        """GET /models: the stored models' resources."""
        return self.request("GET", "/models").parsed()["models"]

    def get_model(self, model_id: str) -> Dict[str, Any]:
        """GET /models/{id}."""
        return self.request("GET", "/models/" + model_id).parsed()

    def delete_model(self, model_id: str) -> None:
        """DELETE /models/{id}."""
        self.request("DELETE", "/models/" + model_id)

    def mesh(self, model_id: str, format: str = "stl", tolerance: Optional[float] = None,
             since: Optional[int] = None) -> bytes:
        """GET /models/{id}/mesh: stl, ply, obj, vtp, vtk or delta; tolerance in mm; with format="delta",
        since=V the changes from version V (0: the whole mesh; a version older than the model's
        journal: SurfdError 410). MeshCopy applies them."""
        return self._job("GET", "/models/%s/mesh" % model_id, {"format": format, "tolerance": tolerance, "since": since})

    def iso(self, model_id: str, value: float) -> Dict[str, Any]:
        """POST /models/{id}/iso?value=V: the model at a new iso, as its next version."""
        return self._job("POST", "/models/%s/iso" % model_id, {"value": value}, b"")

    def patches(self, model_id: str) -> Dict[str, Any]:
        """GET /models/{id}/patches: the model's Bezier patches as a scene /render takes."""
        return self._job("GET", "/models/%s/patches" % model_id)

    def rtstruct(self, model_id: str, spacing: Optional[float] = None, format: Optional[str] = None) -> bytes:
        """GET /models/{id}/rtstruct: the model as a DICOM RT Structure Set (bytes of a .dcm), its
        contours spacing mm apart (None: a contour model's own slices, an isosurface's grid);
        format="seg": a DICOM Segmentation on its CT's grid (or spacing's)."""
        return self._job("GET", "/models/%s/rtstruct" % model_id, {"spacing": spacing, "format": format})

    def rtstruct_set(self, model_ids: List[str], spacing: Optional[float] = None,
                     format: Optional[str] = None) -> bytes:
        """GET /rtstruct?models=ID,...: several models as one DICOM RT Structure Set, an ROI each
        (format="seg": one DICOM Segmentation, a segment each)."""
        return self._job("GET", "/rtstruct", {"models": ",".join(model_ids), "spacing": spacing, "format": format})

    # ---- the DICOM network (series received or pulled, PACS) ------------------------------

    def series(self, uid: Optional[str] = None) -> Union[List[Dict[str, Any]], Dict[str, Any]]:
        """GET /series (the DICOM series received by the node or pulled), or GET /series/{uid}: one,
        with its geometry (dims, spacing, orientation)."""
        if uid is None:
            return self.request("GET", "/series").parsed()["series"]
        return self.request("GET", "/series/" + uid).parsed()

    def delete_series(self, uid: str) -> None:
        """DELETE /series/{uid}: the series and its instances."""
        self.request("DELETE", "/series/" + uid)

    def studies(self, pacs: str, **query: Any) -> List[Dict[str, Any]]:
        """GET /pacs/{pacs}/studies?...: a search of a configured PACS (PatientID=..., StudyDate=...),
        its DICOM JSON as the PACS answers it."""
        return self.request("GET", "/pacs/%s/studies%s" % (pacs, _query(query))).parsed()

    def pull(self, pacs: str, study: str, series: Optional[str] = None) -> Dict[str, Any]:
        """POST /series/pull: a study's series (or one) from a configured PACS into the store; what
        was kept ({"series": [{"uid", "instances"}], "instances"})."""
        return self._job("POST", "/series/pull", {"pacs": pacs, "study": study, "series": series}, b"")

    def send(self, model_id: str, pacs: str, as_: str = "rtstruct", spacing: Optional[float] = None) -> Dict[str, Any]:
        """POST /models/{id}/send: the model to a configured PACS as an RT Structure Set (as_="rtstruct")
        or a DICOM Encapsulated STL ("dicom-stl"); what the PACS said of each instance."""
        return self._job("POST", "/models/%s/send" % model_id, {"pacs": pacs, "as": as_, "spacing": spacing}, b"")

    def view(self, model_id: str, **options: Any) -> bytes:
        """GET /models/{id}/render with render's options: the image."""
        return self._job("GET", "/models/%s/render" % model_id, options)

    def version(self) -> Dict[str, Any]:
        """GET /version."""
        return self.request("GET", "/version").parsed()

    def metrics(self) -> str:
        """GET /metrics: Prometheus text."""
        return self.request("GET", "/metrics").body.decode()


class MeshCopy:
    """A model's mesh held by triangle id, kept up to date by mesh deltas (API.md, "Interactive
    isosurfaces"): what a viewer or a script that follows a model's edits holds. triangles: id ->
    nine floats (three corners, patient mm); version: the model's version they are of.

        copy = MeshCopy(client, model_id)      # GET mesh?format=delta&since=0
        client.edit(model_id, samples, region)
        copy.update()                          # only the change: since=copy.version
    """

    def __init__(self, client: "Client", model_id: str):
        self.client, self.model_id = client, model_id
        self.triangles: Dict[int, tuple] = {}
        self.version = 0
        self.update()

    def apply(self, delta: bytes) -> None:
        """Applies one delta (its from version must be this copy's; 0: the whole mesh)."""
        import struct
        if delta[:4] != b"SFMD" or len(delta) < 20:
            raise ValueError("not a mesh delta")
        frm, to, n_removed, n_added = struct.unpack_from("<4I", delta, 4)
        if len(delta) != 20 + 4 * n_removed + 40 * n_added:
            raise ValueError("a mesh delta whose counts do not match its length")
        if frm != self.version:
            raise ValueError("a delta from version %d, the copy is of %d" % (frm, self.version))
        if frm == 0:
            self.triangles = {}
        for tid in struct.unpack_from("<%dI" % n_removed, delta, 20):
            del self.triangles[tid]
        at = 20 + 4 * n_removed
        for k in range(n_added):
            tid, *corners = struct.unpack_from("<I9f", delta, at + 40 * k)
            self.triangles[tid] = tuple(corners)
        self.version = to

    def update(self) -> int:
        """The changes since this copy's version applied (the whole mesh again when the model's
        journal no longer reaches back to it); the version now."""
        try:
            self.apply(self.client.mesh(self.model_id, format="delta", since=self.version))
        except SurfdError as e:
            if e.status != 410:
                raise
            self.version = 0
            self.apply(self.client.mesh(self.model_id, format="delta", since=0))
        return self.version


class Response:
    """An HTTP answer: status, headers, body (bytes)."""

    def __init__(self, status: int, headers: Dict[str, str], body: bytes):
        self.status, self.headers, self.body = status, headers, body

    def parsed(self) -> Union[Dict[str, Any], bytes]:
        """The body as JSON when it is JSON, else the bytes."""
        ctype = next((v for k, v in self.headers.items() if k.lower() == "content-type"), "")
        if "json" in ctype and self.body:
            return json.loads(self.body)
        return self.body


def _query(options: Optional[Options]) -> str:
    if not options:
        return ""
    pairs = []
    for k, v in options.items():
        if v is None:
            continue
        if isinstance(v, bool):
            v = "true" if v else "false"
        elif isinstance(v, (list, tuple)):
            v = ",".join(str(x) for x in v)
        pairs.append((k, str(v)))
    return "?" + urllib.parse.urlencode(pairs, quote_via=urllib.parse.quote, safe=",") if pairs else ""


def _is_file(s: str) -> bool:
    try:
        return len(s) < 4096 and not s.lstrip().startswith(("{", "[")) and Path(s).is_file()
    except OSError:  # a text too long for a file name
        return False


def _is_dir(s: Body) -> bool:
    try:
        return isinstance(s, (str, os.PathLike)) and len(str(s)) < 4096 and Path(s).is_dir()
    except OSError:
        return False


def _series_image(name: str, data: bytes) -> bool:
    """Whether a file of a series' directory is one of its images: DICOM ("DICM" after the preamble,
    or a first element of group 0002 or 0008 without one), and not the media's DICOMDIR."""
    if name.upper() == "DICOMDIR":
        return False
    return data[128:132] == b"DICM" or (len(data) >= 8 and data[1] == 0 and data[0] in (2, 8))


def _multipart(parts):
    """(name, filename, type, bytes) parts as a multipart/form-data body and its Content-Type."""
    boundary = "surfd-py-" + os.urandom(12).hex()
    out = bytearray()
    for name, filename, ctype, data in parts:
        out += ("--%s\r\nContent-Disposition: form-data; name=\"%s\"; filename=\"%s\"\r\n"
                "Content-Type: %s\r\n\r\n" % (boundary, name, filename, ctype)).encode()
        out += data + b"\r\n"
    out += ("--%s--\r\n" % boundary).encode()
    return bytes(out), "multipart/form-data; boundary=" + boundary


def _series(directory: Path):
    """A directory's images (a DICOM series, one image a file; hidden files, the DICOMDIR and files
    that are not DICOM skipped, in name order) as multipart/form-data, one part "slice" a file,
    named slice0001.dcm ... (a series' own file names may name the patient)."""
    files = sorted(p for p in directory.iterdir() if p.is_file() and not p.name.startswith("."))
    images = [d for p in files for d in (p.read_bytes(),) if _series_image(p.name, d)]
    if not images:
        raise SurfdError(0, {"detail": "%s holds no DICOM images" % directory})
    return _multipart(("slice", "slice%04d.dcm" % k, "application/dicom", d) for k, d in enumerate(images, 1))


def _data_file(data: bytes) -> Optional[str]:
    """The data file a detached header names (NRRD's "data file: F", MetaImage's "ElementDataFile = F",
    not LOCAL, a list or a pattern), else None."""
    nrrd = data[:4] == b"NRRD"
    if not nrrd and not data[:5] == b"NDims" and not data[:10] == b"ObjectType":
        return None
    for line in data[:1 << 22].split(b"\n")[:4096]:  # (the daemon's HEADER_MAX_LINES)
        line = line.rstrip(b"\r")
        if nrrd and not line:
            return None  # the end of an NRRD header: its data follow
        key, sep, value = line.partition(b":" if nrrd else b"=")
        if sep and key.strip() in (b"data file", b"datafile", b"ElementDataFile"):
            value = value[1:] if nrrd and value.startswith(b"=") else value
            value = value.strip().decode("utf-8", "replace")
            return None if value == "LOCAL" or value.startswith("LIST") or "%" in value else value
    return None


def _pair(path: Path, header: bytes, data_file: str):
    """A detached header and the data file it names, beside it, as the two parts of multipart/form-data
    POST /isosurface takes."""
    data_path = path.parent / data_file
    return _multipart([("header", path.name, "text/plain", header),
                       ("data", data_path.name, "application/octet-stream", data_path.read_bytes())])


def _body(body: Optional[Body], content_type: Optional[str], media_of: Callable[[Path], Optional[str]]):
    """(bytes, Content-Type) of a body given as bytes, text, a path (its type by extension: media_of; a
    detached header with the data file it names: _pair) or a directory (a DICOM series: _series)."""
    if body is None:
        return None, content_type
    if _is_dir(body):
        return _series(Path(body))
    if isinstance(body, os.PathLike) or (isinstance(body, str) and _is_file(body)):
        path = Path(body)
        data = path.read_bytes()
        data_file = None if content_type else _data_file(data)
        if data_file:
            return _pair(path, data, data_file)
        return data, content_type or media_of(path) or "application/octet-stream"
    if isinstance(body, str):
        return body.encode(), content_type or "application/json"
    return bytes(body), content_type or "application/octet-stream"
