"""OpenCV's hand-eye solvers on one data set (run by bench_handeye.py in an OpenCV 4 venv).

OpenCV 5.0 has no ``cv2.calibrateHandEye``; this script runs under an OpenCV 4.x python
(``opencv-python-headless==4.10.0.84``) and imports nothing of calib. Input (``.npz``):
``object`` (k, 3) board corners [m], ``pixels`` (images, k, 2) [px], ``K`` (3, 3), ``dist``,
``R_g2b`` (images, 3, 3) and ``t_g2b`` (images, 3) [m] the gripper's pose in the base, and
``eye_in_hand`` (bool). Each image's board pose by ``cv2.solvePnP`` (as users do), then each
method of ``cv2.calibrateHandEye``. Output (JSON on stdout): for each method, the camera's
pose (4x4) in the gripper (eye-in-hand) or in the base (eye-to-hand: the robot's poses
inverted, as OpenCV's documentation says).

Run: /path/to/opencv4/python benchmarks/handeye_peer.py DATA.npz
"""

import json
import sys

import cv2
import numpy as np

METHODS = ("TSAI", "PARK", "HORAUD", "ANDREFF", "DANIILIDIS")


def main(path: str) -> None:
    d = np.load(path)
    R_t2c, t_t2c = [], []
    for uv in d["pixels"]:
        ok, rvec, tvec = cv2.solvePnP(d["object"], uv, d["K"], d["dist"])
        if not ok:
            raise SystemExit("solvePnP failed")
        R_t2c.append(cv2.Rodrigues(rvec)[0])
        t_t2c.append(tvec.ravel())
    R, t = d["R_g2b"], d["t_g2b"]
    if not bool(d["eye_in_hand"]):  # eye-to-hand: the base's pose in the gripper
        R = np.transpose(R, (0, 2, 1))
        t = -np.einsum("nij,nj->ni", R, t)
    out = {"opencv": cv2.__version__}
    for name in METHODS:
        method = getattr(cv2, f"CALIB_HAND_EYE_{name}")
        R_c, t_c = cv2.calibrateHandEye(list(R), list(t), R_t2c, t_t2c, method=method)
        T = np.eye(4)
        T[:3, :3], T[:3, 3] = R_c, np.ravel(t_c)
        out[name] = T.tolist()
    print(json.dumps(out))


if __name__ == "__main__":
    main(sys.argv[1])
