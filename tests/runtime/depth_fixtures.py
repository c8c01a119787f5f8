"""Test files built to each format's field definitions: GDepth JPEGs and tiny ONNX depth models
(no torch), plus an analytic outdoor scene (level camera over a ground plane, a wall, sky)."""

from __future__ import annotations

import base64
import io
import math
import struct
from pathlib import Path

import numpy as np
from PIL import Image

from outcast_core.runtime.geometry.camera import Camera

XMP_SIG = b"http://ns.adobe.com/xap/1.0/\x00"
EXT_SIG = b"http://ns.adobe.com/xmp/extension/\x00"
GUID = "0123456789ABCDEF0123456789ABCDEF"


def outdoor_scene(height: int = 48, width: int = 64, fov_deg: float = 60.0,
                  camera_height: float = 1.6) -> tuple[np.ndarray, Camera]:
    """z depth of a level camera ``camera_height`` above a ground plane, with a wall 2 m wide
    and 2 m tall at z = 8 straight ahead; sky (``inf``) above the horizon."""
    cam = Camera.from_fov(height, width, fov_deg)
    x = (np.arange(width) + 0.5 - cam.cx) / cam.focal
    y = (np.arange(height) + 0.5 - cam.cy) / cam.focal
    xs, ys = np.meshgrid(x, y)
    with np.errstate(divide="ignore"):
        ground = np.where(ys > 0, camera_height / ys, np.inf)
    wall = (np.abs(xs * 8.0) <= 1.0) & (ys * 8.0 <= camera_height) & (ys * 8.0 >= -0.4)
    depth = np.where(wall & (ground > 8.0), 8.0, ground)
    return depth.astype(np.float32), cam


def encode_inverse_image(depth: np.ndarray) -> tuple[np.ndarray, float]:
    """A photo whose red channel is ``(1 / z) / max(1 / z)`` (0 on sky); sky blue, ground
    green-grey. Returns ``(image_srgb, max inverse depth)``."""
    inv = np.where(np.isfinite(depth), 1.0 / depth, 0.0)
    top = float(inv.max())
    sky = ~np.isfinite(depth)
    img = np.empty(depth.shape + (3,), np.float32)
    img[..., 0] = inv / top
    img[..., 1] = np.where(sky, 0.5, 0.4)
    img[..., 2] = np.where(sky, 0.9, 0.2)
    return img, top


# ------------------------------------------------------------------------------------- JPEG


def _segment(marker: int, payload: bytes) -> bytes:
    assert len(payload) + 2 <= 0xFFFF
    return bytes([0xFF, marker]) + struct.pack(">H", len(payload) + 2) + payload


def gdepth_jpeg(path: Path, photo: np.ndarray, depth_png: bytes, *, fmt: str, near: float,
                far: float, mime: str = "image/png", orientation: int = 1,
                extra: str = "", chunk: int = 1000, data_in_extended: bool = True) -> Path:
    """A JPEG of ``photo`` with GDepth XMP; the base64 data in the extended XMP, split into
    ``chunk``-byte pieces (written out of order, as the format allows)."""
    buf = io.BytesIO()
    exif = Image.Exif()
    if orientation != 1:
        exif[0x0112] = orientation
    Image.fromarray((np.clip(photo, 0, 1) * 255).round().astype(np.uint8)).save(
        buf, "JPEG", quality=95, exif=exif.tobytes())
    jpeg = buf.getvalue()
    data = base64.b64encode(depth_png).decode("ascii")
    gd = (f'GDepth:Format="{fmt}" GDepth:Near="{near}" GDepth:Far="{far}" '
          f'GDepth:Mime="{mime}" {extra}')
    ns = ('xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#" '
          'xmlns:GDepth="http://ns.google.com/photos/1.0/depthmap/" '
          'xmlns:xmpNote="http://ns.adobe.com/xmp/note/"')
    if data_in_extended:
        main = (f'<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF {ns}><rdf:Description '
                f'rdf:about="" {gd} xmpNote:HasExtendedXMP="{GUID}"/></rdf:RDF></x:xmpmeta>')
        ext = (f'<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF {ns}><rdf:Description '
               f'rdf:about="" GDepth:Data="{data}"/></rdf:RDF></x:xmpmeta>').encode()
    else:
        main = (f'<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF {ns}><rdf:Description '
                f'rdf:about="" {gd}><GDepth:Data>{data}</GDepth:Data></rdf:Description>'
                f'</rdf:RDF></x:xmpmeta>')
        ext = b""
    segments = [_segment(0xE1, XMP_SIG + main.encode())]
    pieces = [(off, ext[off:off + chunk]) for off in range(0, len(ext), chunk)]
    for off, piece in reversed(pieces):
        segments.append(_segment(0xE1, EXT_SIG + GUID.encode() + struct.pack(
            ">II", len(ext), off) + piece))
    path.write_bytes(jpeg[:2] + b"".join(segments) + jpeg[2:])
    return path


def png_bytes(values: np.ndarray) -> bytes:
    """8-bit (uint8) or 16-bit (uint16) grey PNG."""
    buf = io.BytesIO()
    arr = np.asarray(values)
    Image.fromarray(arr.astype(np.uint16) if arr.dtype == np.uint16 else arr.astype(np.uint8)
                    ).save(buf, "PNG")
    return buf.getvalue()


def range_inverse(depth: np.ndarray, near: float, far: float) -> np.ndarray:
    """Google's RangeInverse ``d_n = far (d - near) / (d (far - near))``."""
    return far * (depth - near) / (depth * (far - near))


def range_linear(depth: np.ndarray, near: float, far: float) -> np.ndarray:
    """Google's RangeLinear ``d_n = (d - near) / (far - near)``."""
    return (depth - near) / (far - near)


# ------------------------------------------------------------------------------------- ONNX


def tiny_depth_model(path: Path, *, input_name: str, output_name: str,
                     size: tuple[int, int] | None, block: int | None, gain: float,
                     offset: float, mean: tuple[float, ...] = (0.485, 0.456, 0.406),
                     std: tuple[float, ...] = (0.229, 0.224, 0.225),
                     output_4d: bool = False, reciprocal: bool = False) -> Path:
    """An ONNX "depth model" that reads the red channel back out of a normalised image:
    ``out = gain * red + offset`` (``1 / that`` with ``reciprocal``). ``block`` adds a
    SpaceToDepth / DepthToSpace pair, which onnxruntime runs only on sides that are multiples
    of ``block`` (14: Depth Anything's ViT patch; 32: MiDaS-like CNNs)."""
    import onnx
    from onnx import TensorProto, helper

    h, w = size if size is not None else ("height", "width")
    x = helper.make_tensor_value_info(input_name, TensorProto.FLOAT, [1, 3, h, w])
    out_shape = [1, 1, h, w] if output_4d else [1, h, w]
    y = helper.make_tensor_value_info(output_name, TensorProto.FLOAT, out_shape)
    # red = x0 * std0 + mean0, so out = gain * std0 * x0 + (gain * mean0 + offset)
    weight = np.zeros((1, 3, 1, 1), np.float32)
    weight[0, 0] = gain * std[0]
    bias = np.array([gain * mean[0] + offset], np.float32)
    inits = [helper.make_tensor("W", TensorProto.FLOAT, weight.shape, weight.ravel()),
             helper.make_tensor("B", TensorProto.FLOAT, [1], bias),
             helper.make_tensor("axes", TensorProto.INT64, [1], [1])]
    nodes = []
    src = input_name
    if block:
        nodes += [helper.make_node("SpaceToDepth", [src], ["s2d"], blocksize=block),
                  helper.make_node("DepthToSpace", ["s2d"], ["d2s"], blocksize=block,
                                   mode="DCR")]
        src = "d2s"
    nodes.append(helper.make_node("Conv", [src, "W", "B"], ["conv"]))
    last = "conv"
    if reciprocal:
        nodes.append(helper.make_node("Reciprocal", [last], ["recip"]))
        last = "recip"
    if output_4d:
        nodes.append(helper.make_node("Identity", [last], [output_name]))
    else:
        nodes.append(helper.make_node("Squeeze", [last, "axes"], [output_name]))
    graph = helper.make_graph(nodes, "tiny_depth", [x], [y], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return path


def finite_corr(a: np.ndarray, b: np.ndarray, mask: np.ndarray) -> float:
    """Pearson correlation of ``a`` and ``b`` on ``mask``."""
    x, y = np.asarray(a, np.float64)[mask], np.asarray(b, np.float64)[mask]
    return float(np.corrcoef(x, y)[0, 1]) if x.size > 2 else math.nan


def dynamic_depth_jpeg(path: Path, photo: np.ndarray, depth_png: bytes, *, fmt: str,
                       near: float, far: float, units: str = "Meters",
                       padding: int = 0) -> Path:
    """A Dynamic Depth JPEG: the photo with a ``Device:Container`` directory (the photo, then
    the depth PNG appended after it) and a camera's ``DepthMap`` naming the PNG's item."""
    buf = io.BytesIO()
    Image.fromarray((np.clip(photo, 0, 1) * 255).round().astype(np.uint8)).save(
        buf, "JPEG", quality=95)
    jpeg = buf.getvalue()
    xmp = (
        '<x:xmpmeta xmlns:x="adobe:ns:meta/"><rdf:RDF '
        'xmlns:rdf="http://www.w3.org/1999/02/22-rdf-syntax-ns#">'
        '<rdf:Description rdf:about="" '
        'xmlns:Device="http://ns.google.com/photos/dd/1.0/device/" '
        'xmlns:Container="http://ns.google.com/photos/dd/1.0/container/" '
        'xmlns:Item="http://ns.google.com/photos/dd/1.0/item/" '
        'xmlns:Camera="http://ns.google.com/photos/dd/1.0/camera/" '
        'xmlns:DepthMap="http://ns.google.com/photos/dd/1.0/depthmap/">'
        "<Device:Container><Container:Directory><rdf:Seq>"
        '<rdf:li rdf:parseType="Resource"><Container:Item Item:Mime="image/jpeg" '
        f'Item:Length="0" Item:Padding="{padding}" Item:DataURI="primary_image"/></rdf:li>'
        '<rdf:li rdf:parseType="Resource"><Container:Item Item:Mime="image/png" '
        f'Item:Length="{len(depth_png)}" Item:DataURI="android/depthmap"/></rdf:li>'
        "</rdf:Seq></Container:Directory></Device:Container>"
        "<Device:Cameras><rdf:Seq><rdf:li rdf:parseType=\"Resource\"><Camera:Camera>"
        f'<Camera:DepthMap DepthMap:Format="{fmt}" DepthMap:Near="{near}" '
        f'DepthMap:Far="{far}" DepthMap:Units="{units}" DepthMap:MeasureType="OpticalAxis" '
        'DepthMap:DepthURI="android/depthmap" DepthMap:ItemSemantic="Depth"/>'
        "</Camera:Camera></rdf:li></rdf:Seq></Device:Cameras>"
        "</rdf:Description></rdf:RDF></x:xmpmeta>"
    )
    primary = jpeg[:2] + _segment(0xE1, XMP_SIG + xmp.encode()) + jpeg[2:]
    path.write_bytes(primary + b"\0" * padding + depth_png)
    return path
