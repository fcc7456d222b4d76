"""``/users``: the clinic's accounts (admin only).  Emails are the login names, unique across clinics: a
taken email answers 409, also when two requests race (the unique constraint decides)."""

from fastapi import APIRouter, HTTPException

from app.store import accounts
from app.web.api.deps import Admin, DbDep
from app.web.api.schemas import UserIn, UserOut, user_out
from app.web.security import Busy, hash_password

router = APIRouter(prefix="/users", tags=["users"])


@router.get("", response_model=list[UserOut])
def list_users(principal: Admin, db: DbDep):
    return [user_out(u) for u in accounts.clinic_users(db, principal.clinic_id)]


@router.post("", response_model=UserOut, status_code=201)
def create_user(body: UserIn, principal: Admin, db: DbDep):
    email = body.email.lower()
    accounts.refuse_taken_email(db, email)  # 409 before the costly hash
    try:
        password_hash = hash_password(body.password)
    except Busy:
        raise HTTPException(503, "The server is busy checking passwords; try again in a moment.",
                            headers={"Retry-After": "5"}) from None
    user = accounts.add_user(db, principal.clinic_id, email=email, name=body.name, role=body.role,
                             password_hash=password_hash)  # 409 also when a concurrent request took the email
    return user_out(user)
