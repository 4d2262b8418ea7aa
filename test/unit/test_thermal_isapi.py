"""Hikvision ISAPI thermal driver: multipart and temperature matrix decoding from the bytes the
camera sends, the shared transport's ResponseStatus handling, and the driver against the fake
camera (401, garbage, timeout, unsupported functions, restart)."""
import json
import os

import cv2
import numpy as np
import pytest

from inspection_robot.camera.driver import DeviceHealth
from inspection_robot.files import read_secret_file
from inspection_robot.isapi import multipart_parts, response_status
from inspection_robot_testing.fake_isapi import FakeIsapiCamera, picture_with_append_data, temperature_matrix_bytes, \
    test_picture as visible_picture, sample_thermal_frame
from inspection_robot.thermal.commands import ThermalCommands, load_radiometric
from inspection_robot.thermal.driver import ThermalError, ThermalRefused, ThermalUnreachable
from inspection_robot.thermal.isapi import IsapiImager, decode_temperature_matrix, imager_from_settings, \
    parse_picture_with_append_data

JPEG = b"\xff\xd8\xff\xe0fake-jpeg\xff\xd9"


def meta(width=3, height=2, size=4, **extra):
    values = {"jpegPicWidth": width, "jpegPicHeight": height, "temperatureDataLength": size,
              "p2pDataLen": width * height * size}
    values.update(extra)
    return values


def test_float32_matrix_is_little_endian_degc_row_by_row():
    data = np.array([[1.5, -20.25, 30.0], [95.5, 0.0, 1200.0]], "<f4").tobytes()
    matrix = decode_temperature_matrix(meta(), data)
    assert matrix.dtype == np.float32 and matrix.shape == (2, 3)
    assert matrix[0, 1] == -20.25 and matrix[1, 2] == 1200.0


def test_16bit_matrix_is_kelvin_times_scale_plus_offset():
    # degC = v / scale + offset - 273.15: 3684 / 10 + 0 - 273.15 = 95.25; unsigned, so 40000 is 4000.0 K
    matrix = decode_temperature_matrix(meta(size=2, scale=10, offset=0),
                                       np.array([3684, 2931, 40000 // 10, 2931, 2931, 2931], "<u2").tobytes())
    assert matrix[0, 0] == pytest.approx(95.25, abs=1e-4) and matrix[0, 1] == pytest.approx(19.95, abs=1e-4)
    assert matrix[0, 2] == pytest.approx(126.85, abs=1e-4)
    with pytest.raises(ValueError, match="no thermographic camera measures that"):
        decode_temperature_matrix(meta(size=2, scale=10, offset=0),
                                  np.array([40000, 2931, 2931, 2931, 2931, 2931], "<u2").tobytes())   # 4000 K
    shifted = decode_temperature_matrix(meta(width=1, height=1, size=2, scale=100, offset=200.0),
                                        np.array([7315], "<u2").tobytes())
    assert shifted[0, 0] == pytest.approx(0.0, abs=1e-4)   # 73.15 + 200 - 273.15


@pytest.mark.parametrize("description, data, reason", [
    (meta(), b"\x00" * 23, "has 23 bytes, 3x2 values of 4 bytes need 24"),
    (meta(p2pDataLen=12), b"\x00" * 24, "p2pDataLen 12 does not match"),
    (meta(size=3), b"\x00" * 18, "temperatureDataLength is 3"),
    (meta(width=0), b"", "jpegPicWidth is 0"),
    (meta(height="2"), b"", "jpegPicHeight is '2'"),
    (meta(width=5000, height=1), b"", "up to 4096"),
    (meta(size=2), b"\x00" * 12, "without a numeric scale and offset"),
    (meta(size=2, scale=0, offset=0), b"\x00" * 12, "scale 0"),
    (meta(width=1, height=1), np.array([np.nan], "<f4").tobytes(), "NaN or infinite"),
])
def test_matrix_that_disagrees_with_its_description_is_refused(description, data, reason):
    with pytest.raises(ValueError, match=reason.replace("(", "\\(")):
        decode_temperature_matrix(description, data)


def test_picture_with_append_data_round_trip_from_the_fakes_bytes():
    frame = sample_thermal_frame(40, 30)
    for size in (4, 2):
        body, content_type = picture_with_append_data(frame, JPEG, visible_picture(), 2, size)
        picture = parse_picture_with_append_data(body, content_type)
        assert picture.jpeg == JPEG and picture.visible_jpeg == visible_picture() and not picture.frozen
        assert np.allclose(picture.matrix, frame, atol=0.05 if size == 2 else 0)


def test_multipart_without_lengths_and_with_the_boundary_inside_binary_data():
    matrix = np.array([[20.0, 21.0]], "<f4").tobytes()
    # Content-Length given: a binary part may contain the delimiter itself
    tricky = b"--xyz\r\n" + matrix
    description = json.dumps({"JpegPictureWithAppendData": meta(width=2, height=1, p2pDataLen=len(tricky))})
    body = (b"--xyz\r\nContent-Type: application/json\r\n\r\n" + description.encode() +
            b"\r\n--xyz\r\nContent-Type: image/jpeg\r\n\r\n" + JPEG +
            b"\r\n--xyz\r\nContent-Type: application/octet-stream\r\nContent-Length: %d\r\n\r\n" % len(tricky)
            + tricky + b"\r\n--xyz--\r\n")
    parts = multipart_parts(body, 'multipart/mixed; boundary="xyz"')
    assert [p[0]["content-type"] for p in parts] == ["application/json", "image/jpeg", "application/octet-stream"]
    assert parts[1][1] == JPEG and parts[2][1] == tricky


@pytest.mark.parametrize("body, content_type, reason", [
    (b"<html>hello</html>", "text/html", "not a multipart answer"),
    (b"junk", "multipart/form-data; boundary=b", "no multipart boundary"),
    (b"--b\r\nContent-Type: image/jpeg\r\nContent-Length: 99\r\n\r\nshort", "multipart/form-data; boundary=b",
     "cut short"),
    (b"--b\r\nContent-Type: image/jpeg\r\n\r\n" + JPEG + b"\r\n--b--", "multipart/form-data; boundary=b",
     "no JpegPictureWithAppendData description"),
    (b"--b\r\nContent-Type: application/json\r\n\r\n{\"x\": 1}\r\n--b--", "multipart/form-data; boundary=b",
     "no JpegPictureWithAppendData object"),
    (b"--b\r\nContent-Type: application/json\r\n\r\n{\"JpegPictureWithAppendData\": {}}\r\n--b--",
     "multipart/form-data; boundary=b", "no temperature matrix"),
])
def test_garbled_pictures_are_refused_with_the_reason(body, content_type, reason):
    with pytest.raises(ValueError, match=reason):
        parse_picture_with_append_data(body, content_type)


def test_response_status_xml_and_json():
    xml = (b'<?xml version="1.0"?><ResponseStatus xmlns="http://www.hikvision.com/ver20/XMLSchema">'
           b"<statusCode>4</statusCode><statusString>Invalid Operation</statusString>"
           b"<subStatusCode>notSupport</subStatusCode></ResponseStatus>")
    assert response_status(xml) == ("4", "notSupport", "Invalid Operation")
    assert response_status(b'{"statusCode": 4, "subStatusCode": "notSupport", "statusString": "Invalid"}') == \
        ("4", "notSupport", "Invalid")
    assert response_status(b"<PTZStatus/>") is None and response_status(b"\xff\xd8") is None


@pytest.fixture
def fake():
    camera = FakeIsapiCamera(user="admin", password="pw").start()
    yield camera
    camera.stop()


def test_driver_reads_the_matrix_picture_and_probe(fake):
    imager = IsapiImager(fake.url, "admin", "pw", 2, 1.0, 2.0)
    assert np.array_equal(imager.frame(), fake.thermal_frame)
    assert imager.capture_jpeg() == fake.thermal_picture
    imager.probe()
    fake.temperature_data_length = 2
    assert imager.frame()[100, 200] == pytest.approx(95.25, abs=0.05)
    assert fake.challenges >= 1
    paths = [path for _, path, _ in fake.requests]
    assert "/ISAPI/Thermal/channels/2/thermometry/jpegPicWithAppendData?format=json" in paths


def test_driver_errors_name_the_setting_to_fix(fake):
    imager = IsapiImager(fake.url, "admin", "pw", 2, 0.3, 0.3)
    fake.set_fault("401")
    with pytest.raises(ThermalRefused, match="HTTP 401.*~isapi/user and ~isapi/password_file"):
        imager.frame()
    fake.set_fault("garbage")
    with pytest.raises(ThermalError, match="not a multipart answer.*~isapi/host and ~isapi/port"):
        imager.frame()
    with pytest.raises(ThermalError, match="malformed XML.*~isapi/host and ~isapi/port"):
        imager.probe()
    with pytest.raises(ThermalError, match="no radiometric picture"):
        imager.capture_jpeg()
    fake.set_fault("timeout")
    with pytest.raises(ThermalUnreachable, match="unreachable.*timed out.*~isapi/host"):
        imager.frame()
    fake.set_fault(None)
    assert imager.frame().shape == (288, 384)   # the same driver again, nothing to reset
    with pytest.raises(ThermalError, match="no thermometry on channel 1.*~isapi/channel"):
        IsapiImager(fake.url, "admin", "pw", 1, 1.0, 1.0).probe()


def test_driver_restart_of_the_camera(fake):
    imager = IsapiImager(fake.url, "admin", "pw", 2, 1.0, 1.0)
    fake.stop()
    with pytest.raises(ThermalUnreachable, match="unreachable"):
        imager.frame()
    fake.start()
    assert imager.frame().shape == (288, 384)


def test_commands_answer_unsupported_for_what_the_camera_lacks(fake, tmp_path):
    imager = IsapiImager(fake.url, "admin", "pw", 2, 1.0, 1.0)
    health = DeviceHealth()
    table = ThermalCommands(imager, [str(tmp_path)], health, 384, 288).table
    assert table.dispatch("auto_focus", "") == ("failed", "unsupported")   # fixed lens
    fake.thermal_focus = True
    assert table.dispatch("auto_focus", "") == ("success", "") and fake.focus_pushes == 1
    assert table.dispatch("get_spot_temperature", "200,100") == ("success", "95.25")
    assert table.dispatch("get_low_temperature", "") == ("success", "18.00")
    reply = table.dispatch("save_temperature", "t.png")
    assert np.allclose(load_radiometric(reply.data), fake.thermal_frame, atol=0.006)
    reply = table.dispatch("capture_picture", "p.jpg")
    with open(reply.data, "rb") as stream:
        assert stream.read() == fake.thermal_picture
    fake.radiometric = False
    assert table.dispatch("get_high_temperature", "") == ("failed", "unsupported")
    assert health.ok   # the camera answered
    fake.set_fault("401")
    ack, reason = table.dispatch("get_high_temperature", "")
    assert ack == "failed" and "~isapi/password_file" in reason and not health.ok
    assert not os.path.exists(str(tmp_path / "q.png"))
    assert table.dispatch("save_temperature", "q.png").ack == "failed"
    assert not os.path.exists(str(tmp_path / "q.png"))   # nothing written


def test_picture_is_the_matrixs_own_or_false_colour(fake, tmp_path):
    table = ThermalCommands(IsapiImager(fake.url, "admin", "pw"), [str(tmp_path)], DeviceHealth(), 384, 288).table
    fake.thermal_picture = visible_picture()   # 320x180: not pixel for pixel the 384x288 matrix
    picture = cv2.imread(table.dispatch("capture_picture", "a.jpg").data)
    assert picture.shape == (288, 384, 3)   # the matrix in false colour instead
    fake.radiometric = False   # no matrix: the camera's streaming picture, whatever its size
    with open(table.dispatch("capture_picture", "b.jpg").data, "rb") as stream:
        assert stream.read() == visible_picture()
    assert fake.requests[-1][1] == "/ISAPI/Streaming/channels/201/picture"


def test_frame_size_other_than_configured_names_the_settings(fake, tmp_path):
    table = ThermalCommands(IsapiImager(fake.url, "admin", "pw"), [str(tmp_path)], DeviceHealth(), 640, 512).table
    assert table.dispatch("get_high_temperature", "") == \
        ("failed", "imager delivered a 384x288 frame, expected 640x512: set infrared_imager ~width and ~height to "
                   "the imager's resolution")


def secret(tmp_path, text="pw", mode=0o600):
    path = tmp_path / "password"
    path.write_text(text)
    os.chmod(str(path), mode)
    return str(path)


def test_settings_build_the_driver_or_name_the_setting(fake, tmp_path):
    imager = imager_from_settings({"host": "127.0.0.1", "port": fake.port, "password_file": secret(tmp_path)})
    assert imager.frame().shape == (288, 384)
    cases = [({"port": 80, "password_file": "x"}, "~isapi/host is not set"),
             ({"host": "h", "port": 70000, "password_file": "x"}, "~isapi/port must be 1..65535"),
             ({"host": "h", "port": "80", "password_file": "x"}, "~isapi/port must be an integer"),
             ({"host": "h"}, "~isapi/password_file is not set"),
             ({"host": "h", "password_file": str(tmp_path / "none")}, "~isapi/password_file .*No such file"),
             ({"host": "h", "password_file": "x", "channel": 0}, "~isapi/channel must be an integer >= 1"),
             ({"host": "h", "password_file": "x", "timeout": 0}, "~isapi/timeout must be a number"),
             ({"host": "h", "password": "pw"}, "unknown setting\\(s\\) password")]
    for settings, reason in cases:
        with pytest.raises(ValueError, match=reason):
            imager_from_settings(settings, lambda path, setting: read_secret_file(path, setting)
                                 if path != "x" else "pw")
    with pytest.raises(ValueError, match="accessible by group/others"):
        imager_from_settings({"host": "h", "password_file": secret(tmp_path, mode=0o644)})


def test_fake_matrix_bytes_are_row_major_little_endian():
    frame = np.array([[1.0, 2.0]], np.float32)
    assert temperature_matrix_bytes(frame) == b"\x00\x00\x80\x3f\x00\x00\x00\x40"
    assert temperature_matrix_bytes(frame, 2, 10.0) == np.array([2742, 2752], "<u2").tobytes()
