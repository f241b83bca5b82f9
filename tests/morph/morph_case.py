"""What the morph tests share: a fresh folder a test, and motion files written into it."""
import json
import os
import shutil
import tempfile
import unittest


class MorphCase(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.mkdtemp(prefix="csrbf-morph-")

    def tearDown(self):
        shutil.rmtree(self.tmp, ignore_errors=True)

    def motion(self, data):
        """Writes data as a new motion file in the test's folder; returns its path."""
        path = os.path.join(self.tmp, "motion-%d.json" % len(os.listdir(self.tmp)))
        with open(path, "w") as f:
            json.dump(data, f)
        return path
