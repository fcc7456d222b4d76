"""``/clinics/current``: the caller's clinic (clinics are created with ``chakamo clinics create``)."""

from fastapi import APIRouter

from app.web.api.deps import Reader
from app.web.api.schemas import ClinicOut

router = APIRouter(prefix="/clinics", tags=["clinics"])


@router.get("/current", response_model=ClinicOut)
def current_clinic(principal: Reader):
    return {"id": principal.clinic_id, "name": principal.clinic_name}
