# 20 M-point LAS 1.4 point format 6 from the sampled dragon PLY (scaled to survey size, UTM offset),
# with LiDAR-like attributes: GPS time rising along the scan, intensity, returns, classification.
import sys, numpy as np, laspy
src, dst = sys.argv[1], sys.argv[2]
with open(src, 'rb') as f:
    while f.readline().strip() != b'end_header':
        pass
    a = np.frombuffer(f.read(), dtype='<f4').reshape(-1, 7)
n = len(a)
xyz = a[:, :3].astype(np.float64) * 1000.0 + np.array([500000.0, 4000000.0, 100.0])
h = laspy.LasHeader(point_format=6, version="1.4")
h.scales = [0.001, 0.001, 0.001]
h.offsets = [500000.0, 4000000.0, 0.0]
las = laspy.LasData(h)
las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
rng = np.random.default_rng(1)
las.gps_time = 1e8 + np.arange(n) * 1e-5
las.intensity = (rng.gamma(2.0, 300.0, n)).clip(0, 65535).astype(np.uint16)
nr = rng.integers(1, 4, n)
las.number_of_returns = nr
las.return_number = np.minimum(rng.integers(1, 4, n), nr)
las.classification = rng.choice([1, 2, 5, 6], n).astype(np.uint8)
las.point_source_id = (np.arange(n) // 2_000_000).astype(np.uint16)
las.write(dst)
