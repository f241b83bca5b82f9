// The Khronos glTF-Validator (npm gltf-validator) on each file given: prints its counts and every
// error and warning, and exits 1 when any file has an error.
//   node tests/export/validate.js NODE_MODULES_DIR FILE.glb [FILE.gltf ...]
"use strict";
const fs = require("fs");
const path = require("path");
const validator = require(path.join(process.argv[2], "gltf-validator"));

async function main() {
  let failed = 0;
  for (const file of process.argv.slice(3)) {
    const bytes = new Uint8Array(fs.readFileSync(file));
    const report = await validator.validateBytes(bytes, {
      uri: file,
      maxIssues: 0,
      externalResourceFunction: (uri) => Promise.reject(new Error("no external resources: " + uri)),
    });
    const s = report.issues;
    console.log(`${file}: ${s.numErrors} errors, ${s.numWarnings} warnings, ${s.numInfos} infos, ${s.numHints} hints;` +
                ` ${report.info.drawCallCount} draw calls, ${report.info.animationCount} animations,` +
                ` ${report.info.totalVertexCount} vertices, morph targets: ${report.info.hasMorphTargets}`);
    for (const m of s.messages)
      if (m.severity <= 1) console.log(`  ${m.severity === 0 ? "error" : "warning"} ${m.code}: ${m.message} (${m.pointer || ""})`);
    if (s.numErrors > 0) failed++;
  }
  process.exit(failed ? 1 : 0);
}
main().catch((e) => { console.error(e); process.exit(2); });
