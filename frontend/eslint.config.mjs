// ESLint (flat config) for the console's scripts and their unit tests. Run from the
// repository root: frontend/node_modules/.bin/eslint -c frontend/eslint.config.mjs frontend tests/frontend
import { pathToFileURL } from "node:url";
import js from "@eslint/js";
import globals from "globals";
import { apiClientRule, clientNames } from "./lint/api_client_rule.mjs";

// The generated API client the pages' calls are checked against (a test points this at
// a client generated from a changed schema, to see the pages' lint fail).
const clientFile = process.env.EXOSTUDY_API_CLIENT
  ? pathToFileURL(process.env.EXOSTUDY_API_CLIENT).href
  : new URL("./static/api_client.js", import.meta.url).href;
const client = clientNames(await import(clientFile));
// A route spelled by hand in a page: only the generated client may spell one.
const HAND_TYPED = "a route spelled by hand: call the generated client (/static/api_client.js) instead";

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
    files: ["frontend/static/**/*.js"],
    ignores: ["frontend/static/api_client.js"],
    plugins: { exostudy: { rules: { "api-client": apiClientRule(client) } } },
    rules: {
      "exostudy/api-client": "error",
      "no-restricted-syntax": ["error",
        { selector: "Literal[value=/\\/(api|ws)\\//]", message: HAND_TYPED },
        { selector: "TemplateElement[value.raw=/\\/(api|ws)\\//]", message: HAND_TYPED }],
    },
  },
  {
    files: ["frontend/eslint.config.mjs", "frontend/lint/**/*.mjs", "tests/frontend/**/*.mjs"],
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
