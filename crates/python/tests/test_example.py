"""The example script runs: two PNGs -> a coloured PLY point cloud."""

import subprocess
import sys

from conftest import REPO


def test_point_cloud_example(tmp_path):
    out = tmp_path / "cloud.ply"
    done = subprocess.run(
        [sys.executable, str(REPO / "examples" / "python_point_cloud.py"), "-o", str(out)],
        capture_output=True, text=True, cwd=tmp_path,
    )
    assert done.returncode == 0, done.stderr
    data = out.read_bytes()
    header = data[: data.index(b"end_header\n")].decode()
    count = int(header.split("element vertex ")[1].split()[0])
    assert count > 50_000  # 288 x 216 with about 90 % valid
    assert len(data) - len(header) - len("end_header\n") == 15 * count
    assert "property uchar red" in header
