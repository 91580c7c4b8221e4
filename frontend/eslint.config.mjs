// ESLint (flat config) for the console's scripts and their unit tests. Run from the
// repository root: frontend/node_modules/.bin/eslint -c frontend/eslint.config.mjs frontend tests/frontend
import js from "@eslint/js";
import globals from "globals";

export default [
  { ignores: ["**/node_modules/**"] },
  js.configs.recommended,
  {
    files: ["frontend/**/*.js"],
    languageOptions: { ecmaVersion: 2023, sourceType: "module", globals: { ...globals.browser } },
  },
  {
    // The CSRF guard runs as a classic script before any module.
    files: ["frontend/static/guard.js"],
    languageOptions: { sourceType: "script" },
  },
  {
    files: ["frontend/eslint.config.mjs", "tests/frontend/**/*.mjs"],
    languageOptions: { ecmaVersion: 2023, sourceType: "module", globals: { ...globals.node } },
  },
  {
    rules: {
      eqeqeq: ["error", "smart"],
      "no-var": "error",
      "prefer-const": "error",
      "no-unused-vars": ["error", { args: "none" }],
      "no-shadow": "error",
    },
  },
];
