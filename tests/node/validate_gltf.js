// node validate_gltf.js VALIDATOR_DIR FILE.glb: Khronos' glTF-Validator report of FILE as JSON on stdout.
const fs = require("fs");
const path = require("path");
const validator = require(path.resolve(process.argv[2]));
validator.validateBytes(new Uint8Array(fs.readFileSync(process.argv[3])), {maxIssues: 100})
  .then((report) => console.log(JSON.stringify(report)))
  .catch((error) => { console.error(`validation failed: ${error}`); process.exit(2); });
