"""The browser's vocabulary: the names its scripts use, from the Python definitions.

Served as an ES module at `/static/vocabulary.js` (it shadows nothing: no such file
exists under `frontend/static`) so pages import it like any other script (public, as
every static asset: it names columns and controllers, nothing of a study), and as JSON
for other clients, behind the login like the rest of the API.
"""

from __future__ import annotations

from fastapi import APIRouter
from fastapi.responses import Response

from backend.api.deps import access
from backend.schemas.vocabulary import Vocabulary, javascript_module, vocabulary

router = APIRouter(tags=["vocabulary"])


@router.get("/api/vocabulary", response_model=Vocabulary, openapi_extra=access("login"))
def vocabulary_json() -> Vocabulary:
    """Tick columns, models, actions, flag bits, controllers, scripts, health fields."""
    return vocabulary()


@router.get("/static/vocabulary.js", include_in_schema=False)
def vocabulary_module() -> Response:
    """The same names as the module every console page imports."""
    return Response(javascript_module(), media_type="text/javascript",
                    headers={"Cache-Control": "no-cache"})
