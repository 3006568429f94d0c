"""The training-size curve of a finished run's results/ with 1, 2, 3, 5 images and with eight training orders.

    python curves.py RESULTS_DIR    (needs results/merl.zarr, logmap/train.zarr, splits.json and
                                     directions/train/nearfield-fov25-error.json; writes the two JSON files here)
"""

import json
import sys
from pathlib import Path

from brdfpipe.acquisition import evaluation
from brdfpipe.core import integrity

SIZES = [10, 20, 30, 40, 50, 60, 70, 80, 90]


def curve(base: Path, test: list[str], *, n_images: int, order_seed: int) -> dict[int, float]:
    rows = evaluation.training_size_curve(base / "merl.zarr", base / "logmap" / "train.zarr",
                                          base / "directions" / "train" / "nearfield-fov25-error.json",
                                          test_materials=test, sizes=SIZES, order_seed=order_seed,
                                          n_images=n_images, eta=40)
    return {int(r["n_train"]): float(r["value"]) for r in rows if r["material"] == "mean" and r["channel"] == "all"}


def main() -> None:
    base, here = Path(sys.argv[1]), Path(__file__).resolve().parent
    test = integrity.read_json(base / "splits.json", kind="splits file")["test"]
    images = {n: curve(base, test, n_images=n, order_seed=2016) for n in (1, 2, 3, 5)}
    orders = {seed: curve(base, test, n_images=2, order_seed=seed) for seed in (2016, 1, 2, 3, 4, 5, 6, 7)}
    (here / "images-1-2-3-5.json").write_text(json.dumps(images, indent=1))
    (here / "orders-2-images.json").write_text(json.dumps({str(k): v for k, v in orders.items()}, indent=1))


if __name__ == "__main__":
    main()
