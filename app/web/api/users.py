"""``/users``: the clinic's accounts (admin only).  Emails are the login names, unique across clinics: a
taken email answers 409, also when two requests race (the unique constraint decides)."""

from fastapi import APIRouter, HTTPException
from sqlalchemy import select
from sqlalchemy.exc import IntegrityError

from app.web.api.deps import Admin, DbDep
from app.web.api.schemas import UserIn, UserOut, user_out
from app.store.models import User
from app.web.security import Busy, hash_password

router = APIRouter(prefix="/users", tags=["users"])


@router.get("", response_model=list[UserOut])
def list_users(principal: Admin, db: DbDep):
    rows = db.scalars(select(User).where(User.clinic_id == principal.clinic_id).order_by(User.id))
    return [user_out(u) for u in rows]


@router.post("", response_model=UserOut, status_code=201)
def create_user(body: UserIn, principal: Admin, db: DbDep):
    email = body.email.lower()
    if db.scalar(select(User.id).where(User.email == email)) is not None:
        raise HTTPException(409, f"The email {email} already has an account; use another email.")
    try:
        password_hash = hash_password(body.password)
    except Busy:
        raise HTTPException(503, "The server is busy checking passwords; try again in a moment.",
                            headers={"Retry-After": "5"}) from None
    user = User(clinic_id=principal.clinic_id, email=email, name=body.name, role=body.role,
                password_hash=password_hash)
    db.add(user)
    try:
        db.flush()
    except IntegrityError:  # created by a concurrent request between the check and the insert
        raise HTTPException(409, f"The email {email} already has an account; use another email.") from None
    db.refresh(user)
    return user_out(user)
