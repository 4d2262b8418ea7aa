"""compression: PNG as rosbridge builds it (checked with OpenCV), fragments, bounded reassembly."""
import base64
import json

import cv2
import numpy as np
import pytest

from inspection_robot.bridge.compression import Defragmenter, FragmentError, fragments, png_decode, png_encode


@pytest.mark.parametrize("text", ["", "a", '{"op":"publish","msg":{"data":"héllo"}}', "x" * 10001])
def test_png_round_trip_and_opencv_reads_the_same_bytes(text):
    data = png_encode(text)
    assert png_decode(data) == text
    image = cv2.imdecode(np.frombuffer(base64.standard_b64decode(data), np.uint8), cv2.IMREAD_COLOR)
    rgb = image[:, :, ::-1].tobytes()  # OpenCV returns BGR; the payload is the RGB byte stream
    assert rgb.rstrip(b"\n").decode("utf-8") == text


def test_fragments_cover_the_text():
    text = json.dumps({"op": "publish", "msg": {"data": "z" * 95}})
    parts = fragments(text, 10, "m1")
    assert [p["num"] for p in parts] == list(range(len(parts)))
    assert all(p["total"] == len(parts) and p["id"] == "m1" and len(p["data"]) <= 10 for p in parts)
    assert "".join(p["data"] for p in parts) == text


def test_defragmenter_out_of_order_duplicates_and_limits():
    now = [0.0]
    defrag = Defragmenter(lambda: now[0], timeout=5.0, max_bytes=50, max_pending=2)
    assert defrag.add("a", 1, 2, "world") is None
    assert defrag.add("a", 1, 2, "world") is None
    assert defrag.add("a", 0, 2, "hello ") == "hello world"
    assert defrag.pending == 0
    with pytest.raises(FragmentError):
        defrag.add("b", 2, 2, "x")
    defrag.add("b", 0, 3, "x")
    with pytest.raises(FragmentError, match="total changed"):
        defrag.add("b", 1, 4, "x")
    defrag.add("c", 0, 2, "x")
    defrag.add("d", 0, 2, "x")
    with pytest.raises(FragmentError, match="too many"):
        defrag.add("e", 0, 2, "x")
    now[0] = 10.0  # c and d expired
    defrag.add("e", 0, 2, "x")
    assert defrag.pending == 1
    with pytest.raises(FragmentError, match="larger"):
        defrag.add("e", 1, 2, "y" * 60)


def test_a_repeated_fragment_number_replaces_its_piece_and_counts_again():
    """issue #39 item 3: the size of a number sent again was not counted, so re-sending small-then-big
    pieces passed max_message_size and held memory without bound."""
    defrag = Defragmenter(lambda: 0.0, max_bytes=50)
    for _ in range(100):   # the same piece again and again: held once
        assert defrag.add("a", 0, 3, "x" * 20) is None
    assert defrag.held_bytes == 20
    assert defrag.add("a", 0, 3, "y") is None   # replaced by a smaller one: its bytes given back
    assert defrag.held_bytes == 1
    assert defrag.add("a", 1, 3, "z" * 45) is None
    with pytest.raises(FragmentError, match="larger than 50 bytes"):
        defrag.add("a", 0, 3, "w" * 10)   # 10 + 45 > 50: refused, the message dropped
    assert defrag.pending == 0 and defrag.held_bytes == 0
    assert defrag.add("b", 0, 2, "y" * 25) is None   # a whole message within the bound still passes
    assert defrag.add("b", 1, 2, "z" * 25) == "y" * 25 + "z" * 25


def test_the_messages_in_progress_share_one_bound_and_clear_frees_them():
    defrag = Defragmenter(lambda: 0.0, max_bytes=50, max_total_bytes=60)
    defrag.add("a", 0, 2, "x" * 40)
    with pytest.raises(FragmentError, match="larger than 60 bytes together"):
        defrag.add("b", 0, 2, "y" * 30)
    assert defrag.pending == 1 and defrag.held_bytes == 40
    defrag.add("c", 0, 2, "é" * 10)   # counted in UTF-8 bytes, as it came over the wire
    assert defrag.held_bytes == 60
    defrag.clear()
    assert defrag.pending == 0 and defrag.held_bytes == 0
