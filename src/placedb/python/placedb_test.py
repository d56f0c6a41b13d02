"""Tests of the placedb Python module on the repository's sample data.

Run by CTest (python_test) with PYTHONPATH=<build>/python and
PLACEDB_DATA_DIR=<repo>/data, or by hand:

    PYTHONPATH=build/python PLACEDB_DATA_DIR=data /usr/bin/python3 src/placedb/python/placedb_test.py
"""

import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import unittest

import numpy as np

import placedb

DATA = os.environ.get(
    "PLACEDB_DATA_DIR",
    os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "..", "data"))
LOOP = os.path.join(DATA, "rtabmap_loop")
IMAGES = os.path.join(LOOP, "images")
TRUTH = os.path.join(LOOP, "ground_truth.csv")
TUM = os.path.join(DATA, "tum_fr3_office_mini")


def image_path(i):
    return os.path.join(IMAGES, "%03d.jpg" % i)


def bonus(k):
    """The whole-image channel's part of a score with the default options."""
    d = placedb.query_option_defaults()
    if k.whole_image_z is None:
        return 0.0
    return d["whole_image_weight"] * max(0.0, k.whole_image_z - d["whole_image_floor"])


def ranking(result):
    """What must agree between two runs of one query (not the times)."""
    return [(k.keyframe_id, k.score, k.num_matches, k.num_inliers) for k in result.ranked]


class PlaceDbTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        placedb.set_log_level("warn")
        cls.tmp = tempfile.mkdtemp(prefix="placedb_python_test_")
        cls.db_dir = os.path.join(cls.tmp, "loop.db")
        cls.report = placedb.build(cls.db_dir, images=IMAGES, first=1, last=20, threads=2)
        cls.db = placedb.PlaceDatabase(cls.db_dir)
        cls.image5 = placedb.read_image(image_path(5))

    @classmethod
    def tearDownClass(cls):
        shutil.rmtree(cls.tmp, ignore_errors=True)

    # ---- build and open ---------------------------------------------------
    def test_build_report(self):
        r = self.report
        self.assertEqual(r["database"], self.db_dir)
        self.assertEqual(r["num_frames"], 20)
        self.assertEqual(r["num_keyframes"], 20)
        self.assertEqual(r["num_skipped"], 0)
        self.assertGreater(r["num_features"], 0)
        self.assertGreater(r["image_bytes"], 0)

    def test_open(self):
        db = self.db
        self.assertEqual(db.size, 20)
        self.assertEqual(len(db), 20)
        self.assertEqual(db.feature_type, "orb")
        self.assertEqual(db.descriptor_width, 32)
        self.assertEqual(db.whole_image_dims, 512)  # the default HOG channel
        self.assertEqual(os.path.realpath(db.directory), os.path.realpath(self.db_dir))
        self.assertEqual(db.keyframe_ids, list(range(1, 21)))
        m = db.manifest
        self.assertIsInstance(m, dict)
        self.assertEqual(m["settings"]["resize"], 1)
        self.assertEqual(m["settings"]["features"]["type"], "orb")
        self.assertEqual(m["source"], "images:%s [1..20]" % IMAGES)  # as `placedb build` says
        self.assertIn("orb", repr(db))
        # The same through open() and with the options checked.
        db2 = placedb.PlaceDatabase.open(self.db_dir, threads=2, expected_features="orb")
        self.assertEqual(db2.size, 20)
        # A small map keeps its features mapped; asked to, or by its size, reads them.
        self.assertFalse(db2.reads_features)
        self.assertTrue(placedb.PlaceDatabase(self.db_dir, read_features=True).reads_features)
        self.assertFalse(placedb.PlaceDatabase(self.db_dir, read_features_above_mb=0).reads_features)
        part = placedb.PlaceDatabase(self.db_dir, partition=(1, 2))
        self.assertEqual(part.keyframe_ids, list(range(11, 21)))
        some = placedb.PlaceDatabase(self.db_dir, keyframes=[3, 5])
        self.assertEqual(some.keyframe_ids, [3, 5])
        # The ids as `placedb info` shows them.
        ids = db.ids
        self.assertEqual((ids["count"], ids["first"], ids["last"]), (20, 1, 20))
        self.assertEqual(ids["next_free"], 21)
        self.assertEqual(ids["removed"], 0)
        self.assertEqual(ids["removed_since"], m["created"])

    def test_keyframe(self):
        k = self.db.keyframe(5)
        self.assertEqual(k.id, 5)
        self.assertEqual(os.path.basename(k.source), "005.jpg")
        self.assertTrue(os.path.isfile(k.stored_image), k.stored_image)
        self.assertIsNone(k.pose)  # an image folder has no poses
        self.assertEqual(k.timestamp, -1.0)
        self.assertEqual(k.original_size, (self.image5.shape[1], self.image5.shape[0]))
        self.assertGreater(k.num_features, 0)
        self.assertNotEqual(k.source_hash, 0)  # recorded at build
        self.assertNotEqual(k.source_hash, self.db.keyframe(6).source_hash)
        kp, desc = self.db.keyframe_features(5)
        self.assertEqual(kp.shape, (k.num_features, 7))
        self.assertEqual(desc.shape, (k.num_features, 32))
        self.assertIn(5, self.db)
        self.assertNotIn(999, self.db)
        with self.assertRaises(KeyError):
            self.db.keyframe(999)
        # Compact keypoints: positions of a 512 x 384 stored image in 1/64 px,
        # no response.
        self.assertTrue(np.all(kp[:, 4] == 0))
        self.assertTrue(np.all((kp[:, 0] * 64) == np.round(kp[:, 0] * 64)))
        self.assertFalse(np.all((kp[:, 0] * 8) == np.round(kp[:, 0] * 8)))
        report = self.db.verify()
        self.assertEqual(report["format_version"], 3)
        self.assertEqual(report["keyframes"], len(self.db))

    # ---- queries ----------------------------------------------------------
    def test_read_image(self):
        im = self.image5
        self.assertEqual(im.dtype, np.uint8)
        self.assertEqual(im.ndim, 3)
        self.assertEqual(im.shape[2], 3)
        self.assertGreater(im.std(), 0)

    def test_query_image_of_the_database(self):
        r = self.db.query(self.image5)
        self.assertTrue(r.matched)
        self.assertIsNotNone(r.best)
        self.assertEqual(r.best.keyframe_id, 5)
        self.assertEqual(r.ranked[0], r.best)
        self.assertTrue(r.best.verified)
        self.assertGreaterEqual(r.best.num_matches, r.best.num_inliers)
        self.assertEqual(r.best.score, r.best.num_inliers + bonus(r.best))
        self.assertGreaterEqual(r.best.score, placedb.query_option_defaults()["min_score"])
        self.assertEqual(os.path.basename(r.best.source), "005.jpg")
        self.assertTrue(os.path.isfile(r.best.stored_image))
        self.assertLessEqual(len(r.ranked), 5)
        scores = [k.score for k in r.ranked]
        self.assertEqual(scores, sorted(scores, reverse=True))
        self.assertEqual(r.num_keyframes, 20)
        self.assertEqual(r.num_examined, 20)
        self.assertAlmostEqual(r.coverage, 1.0)
        self.assertEqual(r.search, "exhaustive")
        self.assertGreater(r.num_query_features, 0)
        self.assertGreater(r.times.extract_ms, 0.0)
        self.assertGreaterEqual(r.times.total_ms, r.times.extract_ms)
        self.assertIn("keyframe 5", repr(r))

    def test_explain_and_draw_match(self):
        image = placedb.read_image(image_path(6))
        r = self.db.query(image, top_k=3)
        best = r.ranked[0]
        e = self.db.explain(image, best.keyframe_id)
        # The same matches and inliers the query counted.
        self.assertEqual(e["keyframe_id"], best.keyframe_id)
        self.assertEqual(e["num_matches"], best.num_matches)
        self.assertEqual(e["num_inliers"], best.num_inliers)
        self.assertEqual(e["query_points"].shape, (best.num_matches, 2))
        self.assertEqual(e["keyframe_points"].shape, (best.num_matches, 2))
        self.assertEqual(int(e["inliers"].sum()), best.num_inliers)
        h, w = image.shape[:2]
        self.assertTrue((e["query_points"] >= 0).all())
        self.assertTrue((e["query_points"][:, 0] < w).all())
        unverified = self.db.explain(image, best.keyframe_id, verify=False)
        self.assertFalse(unverified["verified"])
        self.assertEqual(unverified["num_inliers"], -1)
        picture = self.db.draw_match(image, best.keyframe_id, "q6")
        self.assertEqual(picture.dtype, np.uint8)
        self.assertEqual(picture.ndim, 3)
        self.assertGreater(picture.shape[1], 2 * 360)
        with self.assertRaises(ValueError):
            self.db.explain(image, 999)
        with self.assertRaises(ValueError):
            self.db.draw_match(np.zeros((0, 0, 3), np.uint8), best.keyframe_id)

    def test_to_dict_is_the_library_json(self):
        r = self.db.query(self.image5)
        d = r.to_dict()
        self.assertEqual(d, json.loads(r.to_json()))
        self.assertEqual(
            set(d), {"matched", "best", "ranked", "num_query_features", "num_keyframes",
                     "num_examined", "num_verified", "coverage", "deadline_reached", "search",
                     "cluster", "times_ms", "decided_by", "sequence"})
        self.assertEqual(d["best"], r.best.to_dict())
        self.assertEqual([k["keyframe_id"] for k in d["ranked"]],
                         [k.keyframe_id for k in r.ranked])
        self.assertEqual(d["times_ms"]["total"], r.times.total_ms)
        self.assertIsNone(d["best"]["pose"])

    def test_sequence_matcher(self):
        # The second lap's frames 41..52 revisit keyframes 1..12 in order.
        seq = placedb.SequenceMatcher(self.db, sequence_length=5, sequence_min_score=3)
        self.assertEqual(seq.frames_held, 0)
        answers = []
        for i in range(41, 53):
            r = seq.query(placedb.read_image(image_path(i)), top_k=5)
            answers.append(r)
            self.assertIsNotNone(r.sequence)
            self.assertIn(r.decided_by, ("frame", "sequence"))
            self.assertEqual(r.to_dict()["sequence"], r.sequence)
        self.assertEqual(answers[0].decided_by, "frame")
        self.assertEqual(seq.frames_held, 5)
        last = answers[-1]
        self.assertEqual(last.decided_by, "sequence")
        self.assertTrue(last.matched)
        self.assertLessEqual(abs(last.best.keyframe_id - 12), 2)
        self.assertEqual(last.decision_score(), last.sequence["score"])
        # feed() takes a result of db.query; reset() forgets.
        seq.reset()
        self.assertEqual(seq.frames_held, 0)
        r = seq.feed(self.db.query(self.image5))
        self.assertEqual(r.decided_by, "frame")
        self.assertEqual(r.sequence["frames"], 1)
        with self.assertRaises(placedb.InvalidArgumentError):
            placedb.SequenceMatcher(self.db, sequence_min_velocity=3, sequence_max_velocity=1)
        with self.assertRaises(TypeError):
            placedb.SequenceMatcher(self.db, sequence_lenght=3)

    def test_whole_image_channel(self):
        self.assertEqual(self.db.whole_image_dims, 512)
        plain = self.db.query(self.image5, whole_image_weight=0, whole_image_candidates=0)
        self.assertIsNone(plain.ranked[0].whole_image)
        self.assertIsNone(plain.ranked[0].whole_image_z)
        r = self.db.query(self.image5, whole_image_weight=4, whole_image_floor=1)
        self.assertEqual(r.best.keyframe_id, 5)
        for k in r.ranked:
            self.assertIsNotNone(k.whole_image)
            self.assertLessEqual(abs(k.whole_image), 1.0)
            expected = (k.num_inliers if k.verified else k.num_matches) + 4 * max(0.0, k.whole_image_z - 1)
            self.assertAlmostEqual(k.score, expected, places=9)
        self.assertGreater(r.ranked[0].whole_image, 0.99)  # the keyframe's own image
        self.assertGreater(r.ranked[0].whole_image_z, 2.0)  # stands out from the map
        self.assertEqual(r.to_dict()["ranked"][0]["whole_image"], r.ranked[0].whole_image)
        self.assertEqual(r.to_dict()["ranked"][0]["whole_image_z"], r.ranked[0].whole_image_z)

    def test_other_layouts_give_the_same_answer(self):
        im = self.image5
        ref = ranking(self.db.query(im))
        # BGRA: the alpha channel is ignored.
        bgra = np.dstack([im, np.full(im.shape[:2], 255, np.uint8)])
        self.assertEqual(ranking(self.db.query(bgra)), ref)
        # Non-contiguous views and Fortran order are copied, not misread.
        wide = np.zeros((im.shape[0], im.shape[1] * 2, 3), np.uint8)
        wide[:, ::2] = im
        self.assertFalse(wide[:, ::2].flags.c_contiguous)
        self.assertEqual(ranking(self.db.query(wide[:, ::2])), ref)
        self.assertEqual(ranking(self.db.query(np.asfortranarray(im))), ref)
        # Gray, made by hand: still the same place.
        gray = (im.astype(np.float32) @ np.array([0.114, 0.587, 0.299], np.float32))
        gray = gray.round().astype(np.uint8)
        self.assertEqual(gray.ndim, 2)
        self.assertEqual(self.db.query(gray).best.keyframe_id, 5)
        self.assertEqual(self.db.query(gray[:, :, None]).best.keyframe_id, 5)

    def test_extract_query_features_round_trip(self):
        kp, desc = self.db.extract(self.image5)
        self.assertEqual(kp.dtype, np.float32)
        self.assertEqual(kp.shape[1], 7)
        self.assertEqual(desc.dtype, np.uint8)
        self.assertEqual(desc.shape, (kp.shape[0], 32))
        self.assertGreater(kp.shape[0], 0)
        self.assertTrue(np.all(kp[:, 0] >= 0) and np.all(kp[:, 0] < self.image5.shape[1]))
        self.assertTrue(np.all(kp[:, 1] >= 0) and np.all(kp[:, 1] < self.image5.shape[0]))
        # Features carry no whole-image row: the image's answer without the channel.
        by_image = self.db.query(self.image5, whole_image_weight=0, whole_image_candidates=0)
        by_features = self.db.query_features(kp, desc)
        self.assertEqual(ranking(by_features), ranking(by_image))
        self.assertEqual(by_features.matched, by_image.matched)
        self.assertEqual(by_features.num_query_features, kp.shape[0])
        self.assertEqual(by_features.times.extract_ms, 0.0)
        # Nx2 keypoints (ORB uses positions only), float64 and non-contiguous
        # descriptors are converted.
        self.assertEqual(self.db.query_features(kp[:, :2], desc).best.keyframe_id, 5)
        self.assertEqual(
            self.db.query_features(kp.astype(np.float64), desc).best.keyframe_id, 5)
        wide = np.zeros((desc.shape[0], 64), np.uint8)
        wide[:, ::2] = desc
        self.assertEqual(ranking(self.db.query_features(kp, wide[:, ::2])), ranking(by_image))
        # Other options apply to features too.
        self.assertLessEqual(len(self.db.query_features(kp, desc, top_k=2).ranked), 2)
        # No features: a valid query with no answer.
        empty = self.db.query_features(np.zeros((0, 7), np.float32), np.zeros((0, 32), np.uint8))
        self.assertFalse(empty.matched)
        self.assertIsNone(empty.best)
        self.assertEqual(empty.ranked, [])

    def test_query_options(self):
        im = self.image5
        r = self.db.query(im, top_k=2)
        self.assertEqual(len(r.ranked), 2)
        r = self.db.query(im, verify=False)
        self.assertTrue(all(not k.verified and k.num_inliers == -1 for k in r.ranked))
        self.assertEqual(r.best.score, r.best.num_matches + bonus(r.best))
        self.assertEqual(r.best.keyframe_id, 5)
        # Above any score: "no match", the ranking is still there.
        r = self.db.query(im, min_score=100000)
        self.assertFalse(r.matched)
        self.assertIsNone(r.best)
        self.assertGreater(len(r.ranked), 0)
        r = self.db.query(im, search="cluster", prior_keyframe=5)
        self.assertTrue(r.search.startswith("cluster"), r.search)
        self.assertEqual(r.best.keyframe_id, 5)
        r = self.db.query(im, search="cluster", prior_pose=placedb.Pose((0, 0, 0)))
        self.assertTrue(r.search.startswith("cluster"), r.search)
        r = self.db.query(im, deadline_ms=1e6, verify_model="homography", verify_seed=3,
                          ratio=0.7, max_hamming=50, cross_check=False, one_to_one=True,
                          min_matches=2, verify_candidates=3, top_k=np.int64(3))
        self.assertLessEqual(r.num_verified, 3)
        self.assertFalse(r.deadline_reached)
        defaults = placedb.query_option_defaults()
        self.assertEqual(defaults["top_k"], 5)
        self.assertEqual(defaults["search"], "exhaustive")

    def test_threads(self):
        images = [placedb.read_image(image_path(i)) for i in (2, 5, 9, 14, 19)]
        expected = [ranking(self.db.query(im)) for im in images]
        got = {}

        def work(t):
            got[t] = [ranking(self.db.query(im)) for im in images]

        threads = [threading.Thread(target=work, args=(t,)) for t in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        self.assertEqual(len(got), 4)
        for t in range(4):
            self.assertEqual(got[t], expected)

    # ---- bad input --------------------------------------------------------
    def test_bad_images(self):
        im = self.image5
        for bad in (im.astype(np.float32), im.astype(np.int16), im.astype(bool),
                    np.zeros((0, 0), np.uint8), np.zeros((0, 10, 3), np.uint8),
                    np.zeros((10, 10, 2), np.uint8), np.zeros((1, 10, 10, 3), np.uint8),
                    np.zeros(10, np.uint8), [[1, 2], [3, 4]]):
            with self.subTest(shape=np.shape(bad), dtype=getattr(bad, "dtype", None)):
                with self.assertRaises(ValueError):
                    self.db.query(bad)
                with self.assertRaises(ValueError):
                    self.db.extract(bad)
        with self.assertRaisesRegex(ValueError, "empty"):
            self.db.query(np.zeros((0, 0), np.uint8))
        with self.assertRaises(TypeError):
            self.db.query(None)
        # Too small for any feature: no answer, not an error.
        self.assertFalse(self.db.query(np.zeros((8, 8), np.uint8)).matched)

    def test_bad_features(self):
        kp, desc = self.db.extract(self.image5)
        cases = {
            "dtype": (kp, desc.astype(np.int32)),
            "float descriptors for orb": (kp, desc.astype(np.float32)),
            "width": (kp, desc[:, :16]),
            "no columns": (kp, np.zeros((len(kp), 0), np.uint8)),
            "1-d descriptors": (kp, desc[0]),
            "rows": (kp[:-1], desc),
            "keypoint columns": (kp[:, :3], desc),
            "keypoint dtype": (kp[:, :2] > 0, desc),
        }
        nan = kp.copy()
        nan[3, 0] = np.nan
        cases["nan position"] = (nan, desc)
        octave = kp.copy()
        octave[3, 5] = 0.5
        cases["fractional octave"] = (octave, desc)
        for name, (k, d) in cases.items():
            with self.subTest(name):
                with self.assertRaises(ValueError):
                    self.db.query_features(k, d)
        with self.assertRaisesRegex(ValueError, "bytes per row"):
            self.db.query_features(kp, desc[:, :16])

    def test_bad_options(self):
        im = self.image5
        for kwargs in ({"top_k": 0}, {"top_k": 2 ** 40}, {"min_score": -1},
                       {"min_score": float("nan")}, {"ratio": 1.5}, {"search": "nope"},
                       {"search": "bow"},  # the database has no bag-of-words index
                       {"verify_model": "affine"}, {"prior_keyframe": -1},
                       {"deadline_ms": -1.0}, {"prior_pose": ((0, 0, 0), (0, 0, 0, 0))},
                       {"prior_pose": (0, 0, 0)}):
            with self.subTest(kwargs):
                with self.assertRaises(ValueError):
                    self.db.query(im, **kwargs)
        with self.assertRaisesRegex(ValueError, "top_k"):
            self.db.query(im, top_k=0)
        for kwargs in ({"top_k": 1.5}, {"top_k": "5"}, {"top_k": True}, {"verify": 1},
                       {"search": 1}, {"topk": 3}, {"prior_pose": "here"}):
            with self.subTest(kwargs):
                with self.assertRaises(TypeError):
                    self.db.query(im, **kwargs)

    def test_bad_open_and_build(self):
        with self.assertRaises(FileNotFoundError):
            placedb.PlaceDatabase(os.path.join(self.tmp, "missing.db"))
        with self.assertRaises(ValueError):
            placedb.PlaceDatabase(self.db_dir, expected_features="surf")
        with self.assertRaises(ValueError):
            placedb.PlaceDatabase(self.db_dir, threads=-1)
        with self.assertRaises(ValueError):
            placedb.PlaceDatabase(self.db_dir, keyframes=[99])
        out = os.path.join(self.tmp, "bad.db")
        for kwargs in ({"resize": 3}, {"features": "sift"}, {"crop": "square"},
                       {"orb_max_features": 0}, {"first": 5, "last": 2}):
            with self.subTest(kwargs):
                with self.assertRaises(ValueError):
                    placedb.build(out, images=IMAGES, **kwargs)
        with self.assertRaises(ValueError):
            placedb.build(out)  # no frames
        # Exists, no overwrite: the message names the keyword, not a flag.
        with self.assertRaisesRegex(ValueError, r"overwrite") as exists:
            placedb.build(self.db_dir, images=IMAGES, last=2)
        self.assertNotIn("--", str(exists.exception))
        with self.assertRaises(TypeError):
            placedb.build(out, images=IMAGES, no_such_setting=1)
        self.assertFalse(os.path.exists(out))
        with self.assertRaisesRegex(FileNotFoundError, r"missing\.png does not exist$"):
            placedb.read_image(os.path.join(self.tmp, "missing.png"))
        # ... and nothing else: no OpenCV warning on stderr.
        run = subprocess.run(
            [sys.executable, "-c", "import placedb\n"
             "try:\n placedb.read_image('/nonexistent/x.png')\n"
             "except FileNotFoundError as e:\n print(e)"],
            capture_output=True, text=True, env=dict(os.environ))
        self.assertEqual(run.returncode, 0, run.stderr)
        self.assertEqual(run.stdout.strip(), "image /nonexistent/x.png does not exist")
        self.assertEqual(run.stderr, "")
        not_an_image = os.path.join(self.tmp, "not_an_image.png")
        with open(not_an_image, "w") as f:
            f.write("text")
        with self.assertRaises(ValueError):
            placedb.read_image(not_an_image)

    # ---- error classes ----------------------------------------------------
    def test_error_classes(self):
        # One class per kind, each also the built-in exception for it.
        for cls, builtin in ((placedb.InvalidArgumentError, ValueError),
                             (placedb.NotFoundError, FileNotFoundError),
                             (placedb.CorruptDatabaseError, ValueError),
                             (placedb.IoError, OSError),
                             (placedb.InternalError, RuntimeError)):
            with self.subTest(cls.__name__):
                self.assertTrue(issubclass(cls, placedb.Error))
                self.assertTrue(issubclass(cls, builtin))
                self.assertEqual(cls.__module__, "placedb")
        self.assertTrue(issubclass(placedb.Error, Exception))
        self.assertFalse(issubclass(placedb.CorruptDatabaseError, placedb.InvalidArgumentError))

    def test_error_kinds(self):
        # A bad option: InvalidArgumentError naming the keyword; where() is
        # kept apart from the message.
        with self.assertRaises(placedb.InvalidArgumentError) as bad:
            self.db.query(self.image5, top_k=0)
        self.assertIn("top_k", str(bad.exception))
        self.assertNotIn(".cc:", str(bad.exception))
        self.assertRegex(bad.exception.where, r"^[a-z_]+/[a-z_]+\.(cc|h):[0-9]+$")
        # No database there: NotFoundError.
        missing = os.path.join(self.tmp, "missing.db")
        with self.assertRaises(placedb.NotFoundError) as gone:
            placedb.PlaceDatabase(missing)
        self.assertIn(missing, str(gone.exception))
        # A damaged manifest: CorruptDatabaseError (also a ValueError).
        damaged = os.path.join(self.tmp, "damaged.db")
        shutil.copytree(self.db_dir, damaged)
        with open(os.path.join(damaged, "manifest.json"), "w") as f:
            f.write("{ not json")
        with self.assertRaises(placedb.CorruptDatabaseError) as corrupt:
            placedb.PlaceDatabase(damaged)
        self.assertIn("manifest.json", str(corrupt.exception))
        with self.assertRaises(ValueError):
            placedb.PlaceDatabase(damaged)
        # A write the system refuses (/proc takes no new files, even from
        # root): IoError, an OSError.
        with self.assertRaises(placedb.IoError):
            placedb.build("/proc/placedb_test.db", images=IMAGES, last=2)
        with self.assertRaises(OSError):
            placedb.build("/proc/placedb_test.db", images=IMAGES, last=2)

    # ---- other sources, settings ------------------------------------------
    def test_build_settings_and_tum(self):
        out = os.path.join(self.tmp, "tum.db")
        r = placedb.build(out, tum=TUM, resize=4, orb_max_features=300, overwrite=True)
        self.assertGreater(r["num_keyframes"], 0)
        db = placedb.PlaceDatabase(out)
        self.assertEqual(db.manifest["settings"]["resize"], 4)
        self.assertEqual(db.manifest["settings"]["features"]["orb"]["max_features"], 300)
        with_pose = [db.keyframe(i) for i in db.keyframe_ids if db.keyframe(i).pose is not None]
        self.assertGreater(len(with_pose), 0)  # TUM frames have ground-truth poses
        k = with_pose[0]
        self.assertGreater(k.timestamp, 0)
        self.assertEqual(len(k.pose.translation), 3)
        q = np.array(k.pose.quaternion_xyzw)
        self.assertAlmostEqual(float(np.linalg.norm(q)), 1.0, places=6)
        m = k.pose.matrix()
        self.assertEqual(m.shape, (4, 4))
        np.testing.assert_allclose(m[:3, 3], k.pose.translation)
        np.testing.assert_allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3), atol=1e-9)
        # A stored frame queried against its own database answers with itself.
        r = db.query(placedb.read_image(k.source))
        self.assertEqual(r.best.keyframe_id, k.id)
        self.assertEqual(r.best.pose, k.pose)
        self.assertEqual(r.to_dict()["best"]["pose"], k.pose.to_dict())
        ev = placedb.evaluate(db, tum=TUM)  # truth from poses
        self.assertTrue(ev["truth"].startswith("poses"), ev["truth"])

    # ---- evaluate ---------------------------------------------------------
    def test_evaluate(self):
        rep = placedb.evaluate(self.db, images=IMAGES, truth=TRUTH, queries=6, seed=1)
        for key in ("num_queries", "num_correct", "num_answerable", "recall_at_1", "recall_at_5",
                    "precision_recall", "latency_ms", "queries", "truth"):
            self.assertIn(key, rep)
        self.assertEqual(rep["num_queries"], 6)
        self.assertEqual(len(rep["queries"]), 6)
        self.assertLessEqual(rep["num_answerable"], rep["num_queries"])
        self.assertLessEqual(rep["num_correct"], rep["num_answerable"])
        self.assertTrue(0.0 <= rep["recall_at_1"] <= rep["recall_at_5"] <= 1.0)
        pr = rep["precision_recall"]
        self.assertTrue(0.0 <= pr["average_precision"] <= 1.0)
        self.assertTrue(0.0 <= pr["at_threshold"]["precision"] <= 1.0)
        lat = rep["latency_ms"]
        self.assertTrue(0.0 < lat["p50"] <= lat["max"])
        self.assertEqual(rep["truth"], "match list")
        ids = [q["query_id"] for q in rep["queries"]]
        self.assertEqual(ids, sorted(ids))
        for q in rep["queries"]:
            self.assertIn(q["query_id"], range(1, 85))
            self.assertEqual(set(q["result"]), set(self.db.query(self.image5).to_dict()))
        # Deterministic: the same seed picks the same queries with the same answers.
        again = placedb.evaluate(self.db, images=IMAGES, truth=TRUTH, queries=6, seed=1)
        self.assertEqual([q["query_id"] for q in again["queries"]], ids)
        self.assertEqual(again["num_correct"], rep["num_correct"])
        # Query options reach the queries.
        unverified = placedb.evaluate(self.db, images=IMAGES, truth=TRUTH, queries=3,
                                      verify=False, top_k=2)
        self.assertFalse(unverified["verified"])
        self.assertTrue(all(len(q["result"]["ranked"]) <= 2 for q in unverified["queries"]))
        # The classic methods on the same queries, beside placedb's answers.
        self.assertEqual(rep["baselines"], {})
        classic = placedb.evaluate(self.db, images=IMAGES, truth=TRUTH, queries=6, seed=1,
                                   baseline="both")
        self.assertEqual(set(classic["baselines"]), {"hog", "seqslam"})
        for b in classic["baselines"].values():
            self.assertTrue(0.0 <= b["recall_at_1"] <= b["recall_at_5"] <= 1.0)
        with self.assertRaises(ValueError):
            placedb.evaluate(self.db, images=IMAGES, truth=TRUTH, queries=1, baseline="gist")
        self.assertEqual(rep["doubts"], [])
        # The database's own frames as queries: said so, refused with strict.
        own = os.path.join(self.tmp, "own_truth.csv")
        with open(own, "w") as f:
            f.write("5,4 5 6\n6,5 6 7\n")
        doubted = placedb.evaluate(self.db, images=IMAGES, truth=own, all=True)
        self.assertEqual(len(doubted["doubts"]), 1)
        self.assertIn("query frames are database frames", doubted["doubts"][0])
        with self.assertRaisesRegex(placedb.InvalidArgumentError, r"refused \(strict\)"):
            placedb.evaluate(self.db, images=IMAGES, truth=own, all=True, strict=True)
        with self.assertRaises(ValueError):
            placedb.evaluate(self.db, images=IMAGES)  # no truth for an image folder
        with self.assertRaises(ValueError):
            placedb.evaluate(self.db, images=IMAGES, truth=TRUTH, queries=0)
        with self.assertRaises(ValueError):
            placedb.evaluate(self.db, images=IMAGES, truth=TRUTH, top_k=0)

    # ---- experiment -------------------------------------------------------
    def test_experiment(self):
        out = os.path.join(self.tmp, "experiment")
        kwargs = dict(images=IMAGES, first=41, last=84, truth=TRUTH, features=["orb"],
                      crop=["none", "chroma"], resize=[4], verification=["on"], queries=4,
                      pictures=1, failures=0)
        s = placedb.experiment(out, database={"first": 1, "last": 40}, report=False, **kwargs)
        self.assertEqual(s["num_settings"], 2)
        self.assertEqual(s["num_reused"], 0)
        self.assertEqual(s["num_queries"], 4)
        self.assertEqual(s["num_database_frames"], 40)
        self.assertIsNone(s["report"])
        with open(s["results"]) as f:
            results = json.load(f)
        self.assertEqual(len(results["settings"]), 2)
        # Resumed: both settings are kept.
        again = placedb.experiment(out, database={"first": 1, "last": 40}, report=False, **kwargs)
        self.assertEqual(again["num_reused"], 2)
        with self.assertRaises(TypeError):
            placedb.experiment(out, database={"no_such_keyword": 1}, **kwargs)
        with self.assertRaises(ValueError):
            placedb.experiment(out, database=3, **kwargs)
        with self.assertRaises(ValueError):
            placedb.experiment(out, **dict(kwargs, resize=[3]))

    def test_docstrings(self):
        self.assertIn("PlaceDatabase", placedb.__doc__)
        self.assertIn("top_k", placedb.PlaceDatabase.query.__doc__)
        self.assertIn("resize", placedb.build.__doc__)
        self.assertIn("recall_at_1", placedb.evaluate.__doc__)
        self.assertIn("verification", placedb.experiment.__doc__)
        self.assertTrue(placedb.__version__)

    @unittest.skipUnless(os.environ.get("PLACEDB_BINARY"), "needs PLACEDB_BINARY (the CLI)")
    def test_every_python_option_of_every_table_is_a_keyword(self):
        """The module against the library's option tables, as `placedb options
        --json` reports them all: every option a table gives Python is a
        keyword of some function (option_defaults() lists each function's),
        with the table's default, and its docstring describes it."""
        out = subprocess.run([os.environ["PLACEDB_BINARY"], "options", "--json"], check=True,
                             capture_output=True, text=True).stdout
        tables = json.loads(out)["tables"]
        self.assertGreaterEqual(len(tables), 9)
        keywords = placedb.option_defaults()
        docs = {"open": placedb.PlaceDatabase.__init__.__doc__,
                "query": placedb.PlaceDatabase.query.__doc__,
                "build": placedb.build.__doc__, "evaluate": placedb.evaluate.__doc__,
                "experiment": placedb.experiment.__doc__,
                "sequence": placedb.SequenceMatcher.__doc__}
        count = 0
        for table in tables:
            for o in table["options"]:
                if not o["python"]:
                    continue
                count += 1
                where = [f for f, kw in keywords.items() if o["name"] in kw]
                self.assertTrue(where, f"{table['table']}: {o['name']} is no Python keyword")
                for f in where:
                    self.assertIn(o["name"], docs[f], f"{f}'s docstring lacks {o['name']}")
        self.assertGreater(count, 80)


class NothingLostTest(unittest.TestCase):
    """Reads write and delete nothing; a manifest nested too deep is refused;
    any file name reaches Python (issue 46)."""

    def setUp(self):
        placedb.set_log_level("warn")
        self.tmp = tempfile.mkdtemp(prefix="placedb_python_nothing_lost_")

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def listing(self, folder):
        out = {}
        for name in sorted(os.listdir(folder)):
            with open(os.path.join(folder, name), "rb") as f:
                out[name] = f.read()
        return out

    def test_reads_never_delete_through_an_images_symlink(self):
        db_dir = os.path.join(self.tmp, "db")
        placedb.build(db_dir, images=IMAGES, last=5)
        shared = os.path.join(self.tmp, "shared")
        shutil.copytree(os.path.join(db_dir, "images"), shared)
        with open(os.path.join(shared, "holiday.png"), "wb") as f:
            f.write(b"mine")
        shutil.rmtree(os.path.join(db_dir, "images"))
        os.symlink(shared, os.path.join(db_dir, "images"))
        debris = os.path.join(db_dir, "manifest.json.tmp.99999999.1")
        with open(debris, "wb") as f:
            f.write(b"a killed writer's")
        before = self.listing(shared)
        db = placedb.PlaceDatabase(db_dir)
        result = db.query(placedb.read_image(image_path(3)))
        self.assertEqual(result.best.keyframe_id, 3)
        db.verify()
        placedb.set_log_level("error")  # the truth names ids beyond these frames
        placedb.evaluate(db, images=IMAGES, first=41, last=46, truth=TRUTH)
        placedb.set_log_level("warn")
        del db
        self.assertEqual(self.listing(shared), before)
        self.assertTrue(os.path.exists(debris), "a read removed a file")

    def test_a_deeply_nested_manifest_is_refused(self):
        db_dir = os.path.join(self.tmp, "db")
        placedb.build(db_dir, images=IMAGES, last=3)
        path = os.path.join(db_dir, "manifest.json")
        with open(path) as f:
            text = f.read()
        for depth in (100000, 1000000):
            with open(path, "w") as f:
                f.write('{"x":' + "[" * depth + "]" * depth + "," + text[1:])
            with self.assertRaises(placedb.CorruptDatabaseError) as caught:
                placedb.PlaceDatabase(db_dir)
            self.assertTrue("nested deeper than 64" in str(caught.exception) or
                            "larger than" in str(caught.exception), str(caught.exception))
        with open(path, "w") as f:
            f.write(text)
        self.assertEqual(len(placedb.PlaceDatabase(db_dir).keyframe_ids), 3)

    def test_a_file_name_that_is_not_utf8_reads_as_os_fsdecode_gives(self):
        folder = os.path.join(os.fsencode(self.tmp), b"images")
        os.makedirs(folder)
        latin1 = os.path.join(folder, b"caf\xe9.jpg")
        shutil.copy(image_path(1), os.fsdecode(latin1))
        shutil.copy(image_path(2), os.fsdecode(os.path.join(folder, b"plain.jpg")))
        db_dir = os.path.join(self.tmp, "db")
        placedb.build(db_dir, images=os.fsdecode(folder))
        db = placedb.PlaceDatabase(db_dir)
        sources = {os.fsencode(db.keyframe(i).source) for i in db.keyframe_ids}
        self.assertIn(latin1, sources)
        self.assertIn(r"caf\udce9.jpg", repr(db.keyframe(db.keyframe_ids[0])) +
                      repr(db.keyframe(db.keyframe_ids[1])))
        result = db.query(placedb.read_image(os.fsdecode(latin1)))
        self.assertEqual(os.fsencode(result.best.source), latin1)
        self.assertTrue(os.path.exists(result.best.stored_image))
        self.assertEqual(os.fsencode(db.directory), os.fsencode(db_dir))


if __name__ == "__main__":
    unittest.main()
