// Validates a glTF file with the Khronos glTF validator (npm package gltf-validator).
// Usage: node validate-gltf.js MODULE_DIR FILE.gltf ; prints the report's issues as JSON and
// exits 1 when it has errors.
const path = require('path');
const fs = require('fs');
const validator = require(path.join(process.argv[2], 'node_modules', 'gltf-validator'));
const file = process.argv[3];
validator
  .validateBytes(new Uint8Array(fs.readFileSync(file)), { uri: path.basename(file) })
  .then((report) => {
    console.log(JSON.stringify(report.issues));
    process.exit(report.issues.numErrors > 0 ? 1 : 0);
  })
  .catch((e) => {
    console.error(String(e));
    process.exit(2);
  });
