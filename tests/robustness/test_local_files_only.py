"""A project names only regular local files in the formats the workstation reads, and nothing
reaches the network: a VRT pointing at ``/vsicurl/http://127.0.0.1:PORT/…`` (a local socket
that records whether it was contacted), a ``/vsi…`` path or a URL as an image, a WMS service
file, a FIFO, a device, a folder, a symbolic-link loop — each refused in one line, at once."""
from __future__ import annotations

import json
import os
import socket
import threading
import time
from contextlib import contextmanager

import pytest
import rasterio

from prismstation.errors import InputError
from prismstation.io.inputs import open_raster_file
from prismstation.io.raster import gdal_env
from tests.robustness import faults as ft


@contextmanager
def listener():
    """A TCP socket on 127.0.0.1 that accepts for the block: yields ``(port, contacts)``, the
    list of the first bytes each connection sent."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    srv.settimeout(0.1)
    contacts, stop = [], threading.Event()

    def serve():
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except OSError:
                continue
            conn.settimeout(1)
            try:
                contacts.append(conn.recv(200))
            except OSError:
                contacts.append(b"")
            conn.close()
    t = threading.Thread(target=serve, daemon=True)
    t.start()
    try:
        yield srv.getsockname()[1], contacts
    finally:
        time.sleep(0.2)  # a connection still on its way is counted
        stop.set()
        t.join(5)
        srv.close()


def _vrt(path, source: str, relative: bool = False) -> None:
    path.write_text(f"""<VRTDataset rasterXSize="800" rasterYSize="800">
  <VRTRasterBand dataType="Byte" band="1">
    <SimpleSource>
      <SourceFilename relativeToVRT="{int(relative)}">{source}</SourceFilename>
      <SourceBand>1</SourceBand>
    </SimpleSource>
  </VRTRasterBand>
</VRTDataset>
""")


def _set_image(sim, view: str, image: str) -> None:
    scene = json.loads((sim / "scene.json").read_text())
    scene["views"][view]["image"] = image
    (sim / "scene.json").write_text(json.dumps(scene))


def test_a_vrt_pointing_at_the_network_is_refused_and_nothing_is_contacted(sim, tmp_path):
    with listener() as (port, contacts):
        _vrt(sim / "N.vrt", f"/vsicurl/http://127.0.0.1:{port}/N.tif")
        _set_image(sim, "N", "N.vrt")
        for argv in (["fit", sim / "p.prismproj"],
                     ["dsm", sim / "p.prismproj", "-o", tmp_path / "d.tif", "--posting", "10"]):
            line = ft.assert_clean_failure(ft.run_cli(argv), argv[0], "N.vrt")
            assert "virtual file system" in line
    assert contacts == []


def test_a_vrt_of_local_files_is_read(sim):
    _vrt(sim / "N.vrt", "N.tif", relative=True)
    with open_raster_file(sim / "N.vrt") as ds:
        assert ds.driver == "VRT" and ds.read(1).any()


@pytest.mark.parametrize("image", ["/vsicurl/http://127.0.0.1:{port}/N.tif", "http://127.0.0.1:{port}/N.tif",
                                   "/vsizip/{sim}/N.zip/N.tif"])
def test_a_vsi_path_or_url_as_an_image_is_refused(sim, image):
    with listener() as (port, contacts):
        _set_image(sim, "N", image.format(port=port, sim=sim))
        ft.assert_clean_failure(ft.run_cli(["fit", sim / "p.prismproj"]), "fit", "views.N.image")
    assert contacts == []


def test_a_service_description_file_is_not_opened(sim):
    """A local GDAL WMS file as an image: its driver is not among those the workstation reads,
    so GDAL never fetches from the server it names."""
    with listener() as (port, contacts):
        (sim / "N.xml").write_text(f"""<GDAL_WMS><Service name="TMS"><ServerUrl>http://127.0.0.1:{port}/${{z}}/${{x}}/${{y}}.png</ServerUrl></Service>
<DataWindow><UpperLeftX>-20037508.34</UpperLeftX><UpperLeftY>20037508.34</UpperLeftY><LowerRightX>20037508.34</LowerRightX>
<LowerRightY>-20037508.34</LowerRightY><TileLevel>1</TileLevel><TileCountX>1</TileCountX><TileCountY>1</TileCountY></DataWindow>
<Projection>EPSG:3857</Projection><BlockSizeX>256</BlockSizeX><BlockSizeY>256</BlockSizeY><BandsCount>1</BandsCount></GDAL_WMS>""")
        _set_image(sim, "N", "N.xml")
        ft.assert_clean_failure(ft.run_cli(["fit", sim / "p.prismproj"]), "fit", "N.xml")
    assert contacts == []


def test_gdal_itself_stays_off_the_network():
    """Should a path get past the checks, the GDAL configuration of every entry point keeps
    /vsicurl/ (and the file systems built on it) from connecting."""
    with listener() as (port, contacts):
        with gdal_env():
            with pytest.raises(rasterio.errors.RasterioIOError):
                rasterio.open(f"/vsicurl/http://127.0.0.1:{port}/x.tif")
    assert contacts == []


def _fifo(path):
    os.mkfifo(path)
    return path


def _loop(path):
    os.symlink(path.name + ".b", path)
    os.symlink(path.name, str(path) + ".b")
    return path


@pytest.mark.parametrize("make", [_fifo, _loop, lambda p: p.mkdir() or p], ids=["fifo", "link loop", "folder"])
@pytest.mark.parametrize("what", ["project", "scene", "image", "DEM", "points"])
def test_a_fifo_a_link_loop_or_a_folder_is_refused_at_once(sim, tmp_path, make, what):
    """Each given as the project, its scene, an image, a DEM, a points file: one line, never a
    hang (a FIFO nobody writes would block its reader for ever) nor a traceback."""
    odd = make(tmp_path / "odd")
    project = sim / "p.prismproj"
    if what == "scene":
        doc = json.loads(project.read_text())
        doc["scene"] = str(odd)
        project.write_text(json.dumps(doc))
    elif what == "image":
        _set_image(sim, "N", str(odd))
    if what == "project":
        argv = ["fit", odd]
    elif what == "DEM":
        argv = ["fit", project, "--dem", odd]
    elif what == "points":
        argv = ["new", tmp_path / "n.prismproj", "--scene", sim / "scene.json", "--points", odd]
    else:
        argv = ["fit", project]
    ft.assert_clean_failure(ft.run_cli(argv), argv[0], ("odd", "scene", "views.N"))


def test_a_device_is_refused():
    with pytest.raises(InputError, match="is a device"):
        open_raster_file("/dev/zero", "reference DEM")
